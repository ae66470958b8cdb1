// The linear response (engine/api/problem.h, issue 16): chosen for a linear FEM reference,
// the rest stiffness's solve, displacements that scale with the load, and the force balance at
// the reference stiffness.
#include <gtest/gtest.h>

#include <cstddef>
#include <vector>

#include "engine/api/model.h"
#include "engine/api/problem.h"
#include "engine/examples/catalog.h"
#include "engine/model/springs.h"
#include "engine/problem/force_balance.h"
#include "io/example_catalog.h"
#include "tests/engine/fit/fit_test_support.h"

namespace springfit {
namespace {

// The reference's springs of an MSS scene, over its own geometry.
ActiveSprings ReferenceSprings(const Scene& s) {
  ActiveSprings springs;
  for (int m = 0; m < static_cast<int>(s.reference.springs.size()); ++m) {
    springs.index.push_back(m);
    springs.stiffness.push_back(s.reference.stiffness.size() == 1 ? s.reference.stiffness[0]
                                                                  : s.reference.stiffness[m]);
  }
  return springs;
}

TEST(Response, DefaultsToLinearForALinearFemReferenceOnly) {
  EXPECT_EQ(ResolveResponse(examples::Make("fem-plate-5x5")), Response::kLinear);
  EXPECT_EQ(ResolveResponse(examples::Make("fem-kidney-2d-nl")), Response::kNonlinear);
  EXPECT_EQ(ResolveResponse(examples::Make("paper-iso-5x5")), Response::kNonlinear);
  EXPECT_EQ(ResolveResponse(WithResponse(examples::Make("fem-plate-5x5"), Response::kNonlinear)),
            Response::kNonlinear);
  const Problem p =
      Problem::Build(WithResponse(examples::Make("paper-iso-5x5"), Response::kLinear));
  EXPECT_EQ(p.response(), Response::kLinear);
  EXPECT_EQ(p.solver_options().response, Response::kLinear);
}

TEST(Response, TheLinearSolveIsTheRestStiffnessSolve) {
  // u = K^-1 f with K = sum k n0 n0^T, assembled here by hand and solved densely.
  const Scene scene = examples::ThinnedGrid({4, 4}, 5, 2.0);
  const int d = scene.dimension, n = scene.node_count();
  const SpringGeometry geometry(d, scene.rest, scene.reference.springs);
  const ActiveSprings springs = ReferenceSprings(scene);
  const Problem problem = Problem::Build(WithResponse(scene, Response::kLinear));
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = problem.load_cases()[k];
    const FreeNodes& free = problem.free_sets()[lc.free_set];
    Matrix K = Matrix::Zero(d * n, d * n);
    for (int m = 0; m < geometry.size(); ++m) {
      const Vector n0 = geometry.rest_separation.segment(d * m, d) / geometry.rest_length[m];
      const Matrix block = springs.stiffness[m] * n0 * n0.transpose();
      const int i = geometry.pairs[m].first, j = geometry.pairs[m].second;
      K.block(d * i, d * i, d, d) += block;
      K.block(d * j, d * j, d, d) += block;
      K.block(d * i, d * j, d, d) -= block;
      K.block(d * j, d * i, d, d) -= block;
    }
    std::vector<int> dofs;
    for (int i = 0; i < n; ++i) {
      if (free.free_index[i] >= 0)
        for (int a = 0; a < d; ++a) dofs.push_back(d * i + a);
    }
    const Vector rhs = lc.force - K * lc.prescribed;  // prescribed is zero on free nodes
    Matrix Kff(dofs.size(), dofs.size());
    Vector fff(dofs.size());
    for (std::size_t r = 0; r < dofs.size(); ++r) {
      fff[r] = rhs[dofs[r]];
      for (std::size_t c = 0; c < dofs.size(); ++c) Kff(r, c) = K(dofs[r], dofs[c]);
    }
    const Vector expected = Kff.ldlt().solve(fff);
    for (std::size_t r = 0; r < dofs.size(); ++r)
      EXPECT_NEAR(lc.reference[dofs[r]], expected[r], 1e-9 * expected.lpNorm<Eigen::Infinity>())
          << "load case " << k << ", dof " << dofs[r];
  }
}

TEST(Response, LinearDisplacementsScaleWithTheLoadNonlinearOnesDoNot) {
  const auto displacement = [](Response response, double factor) {
    Scene s = WithResponse(examples::Make("paper-iso-5x5"), response);
    for (LoadCase& lc : s.load_cases) {
      for (NodalLoad& f : lc.forces) f.value *= factor;
    }
    return Problem::Build(std::move(s)).load_cases()[0].reference;
  };
  const Vector lin1 = displacement(Response::kLinear, 1.0);
  const Vector lin4 = displacement(Response::kLinear, 4.0);
  EXPECT_LT((lin4 - 4.0 * lin1).norm(), 1e-10 * lin4.norm());
  const Vector nl1 = displacement(Response::kNonlinear, 1.0);
  const Vector nl4 = displacement(Response::kNonlinear, 4.0);
  EXPECT_GT((nl4 - 4.0 * nl1).norm(), 1e-3 * nl4.norm());
}

TEST(Response, TheForceBalanceHoldsAtTheLinearReferenceStiffness) {
  // The linearised spring's force per unit stiffness, at the linear equilibria: A w = b exactly.
  const Problem problem =
      Problem::Build(WithResponse(examples::ThinnedGrid({4, 4}, 3, 2.0), Response::kLinear));
  const ForceBalance fb = AssembleForceBalance(problem);
  const std::vector<double> truth = problem.ReferenceWeights();
  const Vector w = Eigen::Map<const Vector>(truth.data(), static_cast<Eigen::Index>(truth.size()));
  EXPECT_LT((fb.a * w - fb.b).norm(), 1e-10 * fb.b.norm());
}

}  // namespace
}  // namespace springfit
