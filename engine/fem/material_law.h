// Hyperelastic material laws of a finite-element reference: strain energy density W(F), first
// Piola-Kirchhoff stress P = dW/dF and its tangent A = dP/dF, per unit reference volume.
//
// With Lamé constants lambda = E nu / ((1 + nu)(1 - 2 nu)), mu = E / (2 (1 + nu)):
//
//   linear               W = mu eps:eps + lambda/2 tr(eps)^2,  eps = sym(F - I)
//                        (small strain: P = sigma, A constant; the energy is quadratic in the
//                        displacement, so its equilibrium is one linear solve)
//   st_venant_kirchhoff  W = mu E:E + lambda/2 tr(E)^2,  E = (F^T F - I) / 2
//                        (P = F S, S = lambda tr(E) I + 2 mu E; as CalculiX's *ELASTIC under
//                        NLGEOM, Abaqus' and FEBio's "St.Venant-Kirchhoff")
//   neo_hookean          W = mu/2 (tr(F^T F) - 3) - mu ln J + lambda/2 (ln J)^2,  J = det F
//                        (the compressible form of Bonet and Wood, "Nonlinear Continuum
//                        Mechanics for Finite Element Analysis", eq. 6.28; FEBio's
//                        "neo-Hookean"; W -> infinity as J -> 0, so no element can invert)
//
// All three agree to first order at F = I (the linear law is the others' linearisation).
//
// 2D: plane strain is the 3D law with F = diag(F2, 1). Plane stress (thin sheet, sigma_zz = 0)
// takes the stretch across the thickness lambda3 that makes dW/dlambda3 = 0 (W's minimum over
// lambda3, so W_plane_stress(F2) = min over lambda3 of W(diag(F2, lambda3))): for the linear and
// the St. Venant-Kirchhoff laws, in which the in-plane and the thickness strains separate, that
// is the in-plane law with lambda replaced by lambda* = 2 lambda mu / (lambda + 2 mu); for the
// neo-Hookean law lambda3 is solved pointwise (Newton on s = ln lambda3, monotone) and the
// tangent is condensed: A = W_FF - W_Fl W_lF / W_ll.
#pragma once

#include "engine/api/scene.h"
#include "engine/linalg/linalg.h"

namespace springfit::fem {

// The Lamé constants of a material, with the plane-stress substitution applied in 2D.
struct LameConstants {
  double lambda = 0.0;
  double mu = 0.0;
};
LameConstants LameOf(const Material& material, int dimension, PlaneMode plane);

// W, P and A at F = I + H, for elements of dimension D. A is stored as a D*D x D*D matrix,
// A(i + D*J, k + D*L) = dP_iJ / dF_kL (column-major flattening of F, as Eigen stores it).
template <int D>
struct MaterialResponse {
  double energy = 0.0;
  MatD<D> stress = MatD<D>::Zero();
  Eigen::Matrix<double, D * D, D * D> tangent;
  // false when F is not admissible (J <= 0 for a law that needs J > 0); the other fields
  // are then unspecified.
  bool admissible = true;
};

// One material law at one point, evaluated at the displacement gradient H = F - I (the linear
// and St. Venant-Kirchhoff strains are formed from H, keeping the digits of small strains).
// `need_tangent` false skips A (energy and stress only).
template <int D>
class MaterialLaw {
 public:
  MaterialLaw() = default;
  MaterialLaw(const Material& material, PlaneMode plane);

  MaterialModel model() const { return model_; }
  MaterialResponse<D> Evaluate(const MatD<D>& H, bool need_tangent) const;

 private:
  MaterialResponse<D> Linear(const MatD<D>& H, bool need_tangent) const;
  MaterialResponse<D> StVenantKirchhoff(const MatD<D>& H, bool need_tangent) const;
  MaterialResponse<D> NeoHookean(const MatD<D>& F, bool need_tangent) const;
  MaterialResponse<D> NeoHookeanPlaneStress(const MatD<D>& F, bool need_tangent) const;

  MaterialModel model_ = MaterialModel::kLinear;
  bool plane_stress_ = false;
  double lambda_ = 0.0;  // plane-stress substituted (linear, St. Venant-Kirchhoff in 2D)
  double mu_ = 0.0;
  double lambda3d_ = 0.0;  // the material's own lambda (neo-Hookean plane stress)
};

}  // namespace springfit::fem
