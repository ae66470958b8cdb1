// Spring geometry and the per-spring mechanics of a mass-spring model.
//
// A spring between nodes i and j with stiffness k and rest length l, at current separation
// d = X_i - X_j with L = |d| and n = d / L, has
//   energy   e = 1/2 k (L - l)^2
//   gradient de/dX_i = k (L - l) n = -de/dX_j         (the force on i is its negative)
//   Hessian  d2e/dX_i2 = K = k [(1 - l/L) I + (l/L) n n^T],  d2e/dX_i dX_j = -K.
// K is positive semi-definite only while the spring is stretched (L >= l). The projected
// Hessian clamps (1 - l/L) at 0, which is always PSD and still exact along n.
// Dimension D is a template parameter so 2D and 3D share one code path.
#pragma once

#include <cmath>
#include <vector>

#include "engine/api/model.h"
#include "engine/linalg/linalg.h"

namespace springfit {

// Per-spring quantities at the current separation, computed once and shared by the energy,
// gradient and Hessian. A spring whose nodes coincide (L = 0) has no direction: its force and
// its Hessian's directional part are taken as zero, so nothing becomes NaN.
//
// The linearised spring (Response::kLinear) keeps its rest direction n0 = d0 / l: its stretch is
// n0 . (u_i - u_j), its energy 1/2 k stretch^2 and its Hessian k n0 n0^T, whatever the
// displacement (the rest stiffness, exact for small loads).
template <int D>
struct SpringState {
  VecD<D> n = VecD<D>::Zero();
  double length = 0.0;   // L (linearised: l + stretch)
  double tension = 0.0;  // k (L - l): the magnitude of the spring's pull
  bool linear = false;

  SpringState(const VecD<D>& d, double rest_length, double k) {
    length = d.norm();
    tension = k * (length - rest_length);
    if (length > 0.0) n = d / length;
  }
  // The linearised spring at displacement difference `du` = u_i - u_j from rest separation d0.
  static SpringState Linearised(const VecD<D>& d0, const VecD<D>& du, double rest_length,
                                double k) {
    SpringState s(d0, rest_length, k);  // n = n0, tension 0 at rest
    const double stretch = s.n.dot(du);
    s.length = rest_length + stretch;
    s.tension = k * stretch;
    s.linear = true;
    return s;
  }
  double Energy(double rest_length, double k) const {
    const double stretch = length - rest_length;
    return 0.5 * k * stretch * stretch;
  }
  // The Hessian block K; `projected` clamps the compressive term.
  MatD<D> Hessian(double rest_length, double k, bool projected) const {
    if (linear) return k * (n * n.transpose());
    if (length == 0.0) return MatD<D>::Zero();
    double lateral = 1.0 - rest_length / length;
    if (projected && lateral < 0.0) lateral = 0.0;
    return k * (lateral * MatD<D>::Identity() + (rest_length / length) * (n * n.transpose()));
  }
};

}  // namespace springfit
