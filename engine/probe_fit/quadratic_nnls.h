// A convex quadratic over the non-negative orthant:
//   minimise q(x) = 1/2 x^T H x - c^T x   subject to x >= 0,
// H symmetric positive semi-definite and dense (the mode lift's dual, mode_lift.h).
//
// Projected Newton (Bertsekas, "Projected Newton methods for optimization problems with simple
// constraints", SIAM J. Control Optim. 20(2), 1982): each iteration fixes the variables at
// their bound whose gradient pushes them out (x_i <= eps and g_i > 0), takes the Newton step on
// the others (a dense Cholesky of H restricted to them, with a relative ridge that keeps it
// positive definite where H is only semi-definite), and searches along the projected arc
// max(x + alpha d, 0) with Armijo's rule. Variables held at 0 by `fixed` stay there.
// On the mode lift's few tens of modes it converges in a few iterations; the Cholesky is the
// cost (m^3 / 3 per iteration).
#pragma once

#include <string>
#include <vector>

#include "engine/linalg/linalg.h"
#include "engine/runtime/interruption.h"

namespace springfit::response {

struct QuadraticNnlsOptions {
  int max_iterations = 60;
  // Converged when the projected gradient's largest entry is at most this times the largest
  // |c_i| (unit-free).
  double tolerance = 1e-9;
  // The ridge added to H's restricted diagonal, relative to its largest diagonal entry: a
  // semi-definite H (springs the probes cannot tell apart) still factorises, and the step then
  // prefers the smallest change. In (0, 1e-2].
  double ridge = 1e-12;
  // When the restricted H with that ridge still fails to factorise (round-off of a singular
  // H), this further ridge is added, relative as above (in (0, 1e-2]).
  double fallback_ridge = 1e-8;
  // Bertsekas' epsilon, the band above 0 where a variable whose gradient points out counts as
  // at its bound, is at most this fraction of max(largest x, 1) (in (0, 1)); narrower when the
  // projected gradient step is.
  double bound_band = 1e-2;
  // Armijo's rule along the projected arc: a step is taken when it lowers q by at least this
  // fraction of the gradient's prediction (in (0, 0.5)), the step halved at most
  // `max_halvings` times (>= 1) before the iteration counts as converged to round-off.
  double armijo = 1e-4;
  int max_halvings = 40;
  void Validate(const std::string& owner = "QuadraticNnlsOptions") const;
};

struct QuadraticNnlsResult {
  Vector x;
  double value = 0.0;  // q(x)
  int iterations = 0;
  bool converged = false;
};

// `start` (>= 0, or empty: 0) is where the iterations begin; `fixed[i]` true holds x_i at 0
// (empty: none). Checks `interruption` between iterations (throws Interrupted).
QuadraticNnlsResult SolveQuadraticNnls(const Matrix& H, const Vector& c, const Vector& start,
                                       const std::vector<bool>& fixed,
                                       const QuadraticNnlsOptions& options = {},
                                       Interruption* interruption = nullptr);

}  // namespace springfit::response
