#include "engine/fem/material_law.h"

#include <cmath>

namespace springfit::fem {
namespace {

// Newton steps for the plane-stress thickness stretch: the iteration is monotone and
// quadratic, so this is far more than it takes (5-6 from any admissible F in practice).
constexpr int kThicknessNewtonSteps = 60;
constexpr double kThicknessTolerance = 1e-15;

template <int D>
constexpr int Flat(int i, int J) {
  return i + D * J;
}

// The neo-Hookean tangent at fixed lambda3 (3D, plane strain, and plane stress before the
// condensation), c = lambda ln J - mu:
//   dP_iJ/dF_kL = mu delta_ik delta_JL + lambda Finv_Lk Finv_Ji - c Finv_Jk Finv_Li
template <int D>
Eigen::Matrix<double, D * D, D * D> NeoHookeanTangent(const MatD<D>& Finv, double mu, double lambda,
                                                      double c) {
  Eigen::Matrix<double, D * D, D * D> a;
  for (int i = 0; i < D; ++i) {
    for (int J = 0; J < D; ++J) {
      for (int k = 0; k < D; ++k) {
        for (int L = 0; L < D; ++L) {
          a(Flat<D>(i, J), Flat<D>(k, L)) = mu * (i == k) * (J == L) +
                                            lambda * Finv(L, k) * Finv(J, i) -
                                            c * Finv(J, k) * Finv(L, i);
        }
      }
    }
  }
  return a;
}

}  // namespace

LameConstants LameOf(const Material& material, int dimension, PlaneMode plane) {
  const double e = material.young;
  const double nu = material.poisson;
  LameConstants c;
  c.mu = e / (2.0 * (1.0 + nu));
  c.lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  if (dimension == 2 && plane == PlaneMode::kStress) {
    // = E nu / (1 - nu^2): finite at nu = 0.5, unlike lambda itself.
    c.lambda = e * nu / (1.0 - nu * nu);
  }
  return c;
}

template <int D>
MaterialLaw<D>::MaterialLaw(const Material& material, PlaneMode plane)
    : model_(material.model), plane_stress_(D == 2 && plane == PlaneMode::kStress) {
  const LameConstants c = LameOf(material, D, plane);
  lambda_ = c.lambda;
  mu_ = c.mu;
  lambda3d_ = LameOf(material, 3, PlaneMode::kStrain).lambda;
}

template <int D>
MaterialResponse<D> MaterialLaw<D>::Evaluate(const MatD<D>& H, bool need_tangent) const {
  switch (model_) {
    case MaterialModel::kLinear:
      return Linear(H, need_tangent);
    case MaterialModel::kStVenantKirchhoff:
      return StVenantKirchhoff(H, need_tangent);
    case MaterialModel::kNeoHookean: {
      const MatD<D> F = MatD<D>::Identity() + H;
      return plane_stress_ ? NeoHookeanPlaneStress(F, need_tangent) : NeoHookean(F, need_tangent);
    }
  }
  return {};
}

template <int D>
MaterialResponse<D> MaterialLaw<D>::Linear(const MatD<D>& H, bool need_tangent) const {
  MaterialResponse<D> r;
  const MatD<D> I = MatD<D>::Identity();
  const MatD<D> eps = 0.5 * (H + H.transpose());
  const double tr = eps.trace();
  r.stress = lambda_ * tr * I + 2.0 * mu_ * eps;
  r.energy = mu_ * eps.squaredNorm() + 0.5 * lambda_ * tr * tr;
  if (need_tangent) {
    r.tangent.setZero();
    for (int i = 0; i < D; ++i) {
      for (int J = 0; J < D; ++J) {
        for (int k = 0; k < D; ++k) {
          for (int L = 0; L < D; ++L) {
            r.tangent(Flat<D>(i, J), Flat<D>(k, L)) =
                lambda_ * (i == J) * (k == L) + mu_ * ((i == k) * (J == L) + (i == L) * (J == k));
          }
        }
      }
    }
  }
  return r;
}

template <int D>
MaterialResponse<D> MaterialLaw<D>::StVenantKirchhoff(const MatD<D>& H, bool need_tangent) const {
  MaterialResponse<D> r;
  const MatD<D> I = MatD<D>::Identity();
  const MatD<D> F = I + H;
  // From H rather than F: F^T F - I would lose the digits of small strains.
  const MatD<D> E = 0.5 * (H + H.transpose() + H.transpose() * H);
  const double tr = E.trace();
  const MatD<D> S = lambda_ * tr * I + 2.0 * mu_ * E;
  r.stress = F * S;
  r.energy = mu_ * E.squaredNorm() + 0.5 * lambda_ * tr * tr;
  if (need_tangent) {
    // dP_iJ/dF_kL = delta_ik S_LJ + lambda F_iJ F_kL + mu ((F F^T)_ik delta_JL + F_iL F_kJ)
    const MatD<D> FFt = F * F.transpose();
    for (int i = 0; i < D; ++i) {
      for (int J = 0; J < D; ++J) {
        for (int k = 0; k < D; ++k) {
          for (int L = 0; L < D; ++L) {
            r.tangent(Flat<D>(i, J), Flat<D>(k, L)) =
                (i == k) * S(L, J) + lambda_ * F(i, J) * F(k, L) +
                mu_ * (FFt(i, k) * (J == L) + F(i, L) * F(k, J));
          }
        }
      }
    }
  }
  return r;
}

template <int D>
MaterialResponse<D> MaterialLaw<D>::NeoHookean(const MatD<D>& F, bool need_tangent) const {
  MaterialResponse<D> r;
  const double J = F.determinant();
  if (!(J > 0.0)) {
    r.admissible = false;
    return r;
  }
  const double log_j = std::log(J);
  const MatD<D> Finv = F.inverse();
  // Plane strain: tr(C) of the 3D F = diag(F2, 1) is tr(C2) + 1, so tr(C) - 3 = tr(C2) - 2.
  r.energy = 0.5 * mu_ * (F.squaredNorm() - D) - mu_ * log_j + 0.5 * lambda_ * log_j * log_j;
  const double c = lambda_ * log_j - mu_;
  r.stress = mu_ * F + c * Finv.transpose();
  if (need_tangent) r.tangent = NeoHookeanTangent<D>(Finv, mu_, lambda_, c);
  return r;
}

template <int D>
MaterialResponse<D> MaterialLaw<D>::NeoHookeanPlaneStress(const MatD<D>& F,
                                                          bool need_tangent) const {
  MaterialResponse<D> r;
  const double J2 = F.determinant();
  if (!(J2 > 0.0)) {
    r.admissible = false;
    return r;
  }
  const double mu = mu_;
  const double lambda = lambda3d_;
  const double log_j2 = std::log(J2);
  // dW/dlambda3 = 0  <=>  g(s) = mu (e^{2s} - 1) + lambda (ln J2 + s) = 0,  s = ln lambda3.
  // g is increasing and convex: Newton from a point with g >= 0 decreases monotonically to the
  // root. g(0) = lambda ln J2; where that is negative, s = -ln J2 gives g = mu (J2^-2 - 1) > 0.
  double s = log_j2 >= 0.0 ? 0.0 : -log_j2;
  for (int it = 0; it < kThicknessNewtonSteps; ++it) {
    const double e2s = std::exp(2.0 * s);
    const double g = mu * (e2s - 1.0) + lambda * (log_j2 + s);
    const double dg = 2.0 * mu * e2s + lambda;
    const double step = g / dg;
    s -= step;
    if (std::abs(step) <= kThicknessTolerance * (1.0 + std::abs(s))) break;
  }
  const double l3 = std::exp(s);
  const double log_j = log_j2 + s;  // ln of the 3D J = J2 lambda3
  r.energy =
      0.5 * mu * (F.squaredNorm() + l3 * l3 - 3.0) - mu * log_j + 0.5 * lambda * log_j * log_j;
  const MatD<D> Finv = F.inverse();
  const double c = lambda * log_j - mu;
  r.stress = mu * F + c * Finv.transpose();  // dW/dF2 at fixed lambda3 (dW/dlambda3 = 0)
  if (need_tangent) {
    // W_FF at fixed lambda3, minus the coupling through lambda3:
    //   W_Fl = lambda / lambda3 Finv^T,  W_ll = mu + (mu + lambda (1 - ln J)) / lambda3^2.
    const double w_ll = mu + (mu + lambda * (1.0 - log_j)) / (l3 * l3);
    const MatD<D> w_fl = (lambda / l3) * Finv.transpose();
    const Eigen::Matrix<double, D * D, 1> w = w_fl.reshaped();  // column-major, as Flat
    r.tangent = NeoHookeanTangent<D>(Finv, mu, lambda, c) - w * w.transpose() / w_ll;
  }
  return r;
}

template class MaterialLaw<2>;
template class MaterialLaw<3>;

}  // namespace springfit::fem
