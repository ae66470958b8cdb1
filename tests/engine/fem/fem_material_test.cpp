// Material laws of the FEM reference: stress and tangent against finite differences of the
// energy, and agreement of the three laws with linear elasticity at small strain.
#include "engine/fem/material_law.h"

#include <gtest/gtest.h>

#include "tests/test_scenes.h"

namespace springfit::fem {
namespace {

struct LawCase {
  MaterialModel model;
  PlaneMode plane;
  const char* name;
};

const LawCase kCases[] = {
    {MaterialModel::kLinear, PlaneMode::kStress, "linear_stress"},
    {MaterialModel::kLinear, PlaneMode::kStrain, "linear_strain"},
    {MaterialModel::kStVenantKirchhoff, PlaneMode::kStress, "svk_stress"},
    {MaterialModel::kStVenantKirchhoff, PlaneMode::kStrain, "svk_strain"},
    {MaterialModel::kNeoHookean, PlaneMode::kStress, "neo_stress"},
    {MaterialModel::kNeoHookean, PlaneMode::kStrain, "neo_strain"},
};

// Relative step of the central differences and the agreement they allow (O(h^2) truncation
// on O(1) quantities, round-off ~ eps / h).
constexpr double kStep = 1e-6;
constexpr double kFdTolerance = 1e-6;

template <int D>
MatD<D> SomeDisplacementGradient(std::uint64_t seed, double size) {
  testing::TestRandom random(seed);
  MatD<D> h;
  for (int i = 0; i < D; ++i) {
    for (int j = 0; j < D; ++j) h(i, j) = size * (2.0 * random.Uniform() - 1.0);
  }
  return h;
}

template <int D>
void CheckDerivatives(const MaterialLaw<D>& law, const MatD<D>& h, const std::string& what) {
  const MaterialResponse<D> r = law.Evaluate(h, true);
  ASSERT_TRUE(r.admissible) << what;
  const double scale_p = r.stress.cwiseAbs().maxCoeff() + 1.0;
  const double scale_a = r.tangent.cwiseAbs().maxCoeff();
  for (int k = 0; k < D; ++k) {
    for (int l = 0; l < D; ++l) {
      MatD<D> plus = h, minus = h;
      plus(k, l) += kStep;
      minus(k, l) -= kStep;
      const MaterialResponse<D> rp = law.Evaluate(plus, false);
      const MaterialResponse<D> rm = law.Evaluate(minus, false);
      const double dw = (rp.energy - rm.energy) / (2.0 * kStep);
      EXPECT_NEAR(dw, r.stress(k, l), kFdTolerance * scale_p)
          << what << " P(" << k << "," << l << ")";
      const MatD<D> dp = (rp.stress - rm.stress) / (2.0 * kStep);
      for (int i = 0; i < D; ++i) {
        for (int j = 0; j < D; ++j) {
          EXPECT_NEAR(dp(i, j), r.tangent(i + D * j, k + D * l), kFdTolerance * scale_a)
              << what << " A(" << i << j << "," << k << l << ")";
        }
      }
    }
  }
}

TEST(MaterialLaw, StressAndTangentAreTheEnergysDerivatives2D) {
  const Material base{MaterialModel::kLinear, 7.0, 0.3};
  for (const LawCase& c : kCases) {
    Material m = base;
    m.model = c.model;
    const MaterialLaw<2> law(m, c.plane);
    for (std::uint64_t seed = 1; seed <= 4; ++seed)
      CheckDerivatives<2>(law, SomeDisplacementGradient<2>(seed, 0.3), c.name);
  }
}

TEST(MaterialLaw, StressAndTangentAreTheEnergysDerivatives3D) {
  for (MaterialModel model :
       {MaterialModel::kLinear, MaterialModel::kStVenantKirchhoff, MaterialModel::kNeoHookean}) {
    const MaterialLaw<3> law(Material{model, 3.0, 0.45}, PlaneMode::kStrain);
    for (std::uint64_t seed = 1; seed <= 4; ++seed)
      CheckDerivatives<3>(law, SomeDisplacementGradient<3>(seed, 0.3), "3d");
  }
}

TEST(MaterialLaw, EveryLawIsLinearElasticityAtRest) {
  // The tangent at F = I is the linear law's, and a tiny strain gives the linear stress.
  for (const LawCase& c : kCases) {
    const Material m{c.model, 5.0, 0.35};
    const MaterialLaw<2> law(m, c.plane);
    const MaterialLaw<2> linear(Material{MaterialModel::kLinear, 5.0, 0.35}, c.plane);
    const auto at_rest = law.Evaluate(MatD<2>::Zero(), true);
    const auto reference = linear.Evaluate(MatD<2>::Zero(), true);
    EXPECT_LT((at_rest.tangent - reference.tangent).cwiseAbs().maxCoeff(), 1e-12 * 5.0) << c.name;
    EXPECT_LT(at_rest.stress.cwiseAbs().maxCoeff(), 1e-14 * 5.0) << c.name;
  }
}

TEST(MaterialLaw, PlaneStressIsTheClosedFormUniaxialLaw) {
  // Uniaxial stress in the plane: sigma_xx = E eps_xx and eps_yy = -nu eps_xx with sigma_yy = 0.
  const double e = 4.0, nu = 0.3, strain = 1e-7;
  const MaterialLaw<2> law(Material{MaterialModel::kLinear, e, nu}, PlaneMode::kStress);
  MatD<2> h = MatD<2>::Zero();
  h(0, 0) = strain;
  h(1, 1) = -nu * strain;
  const auto r = law.Evaluate(h, false);
  EXPECT_NEAR(r.stress(0, 0), e * strain, 1e-12 * e * strain);
  EXPECT_NEAR(r.stress(1, 1), 0.0, 1e-12 * e * strain);
  // Plane strain: sigma_xx = E (1 - nu) / ((1 + nu)(1 - 2 nu)) eps_xx under eps_yy = 0.
  const MaterialLaw<2> strain_law(Material{MaterialModel::kLinear, e, nu}, PlaneMode::kStrain);
  MatD<2> h2 = MatD<2>::Zero();
  h2(0, 0) = strain;
  const double expected = e * (1.0 - nu) / ((1.0 + nu) * (1.0 - 2.0 * nu)) * strain;
  EXPECT_NEAR(strain_law.Evaluate(h2, false).stress(0, 0), expected, 1e-12 * expected);
}

TEST(MaterialLaw, NeoHookeanPlaneStressHasNoThroughThicknessStress) {
  // The condensed plane-stress law equals the 3D law at the stretch lambda3 that makes the
  // 3D sigma_zz vanish: compare its in-plane stress with the 3D law at F = diag(F2, lambda3),
  // lambda3 found here by bisection on P_zz.
  const Material m{MaterialModel::kNeoHookean, 2.0, 0.4};
  const MaterialLaw<2> plane(m, PlaneMode::kStress);
  const MaterialLaw<3> solid(m, PlaneMode::kStrain);
  MatD<2> h2;
  h2 << 0.25, 0.05, -0.1, -0.08;
  auto h3_of = [&](double l3) {
    MatD<3> h3 = MatD<3>::Zero();
    h3.topLeftCorner<2, 2>() = h2;
    h3(2, 2) = l3 - 1.0;
    return h3;
  };
  double lo = 0.2, hi = 3.0;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (solid.Evaluate(h3_of(mid), false).stress(2, 2) > 0.0 ? hi : lo) = mid;
  }
  const auto r3 = solid.Evaluate(h3_of(0.5 * (lo + hi)), false);
  const auto r2 = plane.Evaluate(h2, false);
  EXPECT_LT((r3.stress.topLeftCorner<2, 2>() - r2.stress).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_NEAR(r3.energy, r2.energy, 1e-10);
}

TEST(MaterialLaw, NeoHookeanRefusesInvertedStates) {
  const MaterialLaw<2> law(Material{MaterialModel::kNeoHookean, 1.0, 0.3}, PlaneMode::kStrain);
  MatD<2> h = MatD<2>::Zero();
  h(0, 0) = -1.5;  // F_xx = -0.5: J < 0
  EXPECT_FALSE(law.Evaluate(h, true).admissible);
  // St. Venant-Kirchhoff has a finite energy there (it does not resist inversion).
  const MaterialLaw<2> svk(Material{MaterialModel::kStVenantKirchhoff, 1.0, 0.3},
                           PlaneMode::kStrain);
  EXPECT_TRUE(svk.Evaluate(h, true).admissible);
}

}  // namespace
}  // namespace springfit::fem
