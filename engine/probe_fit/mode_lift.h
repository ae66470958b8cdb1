// Step 4 of the probe fit (response_fit.h): the smallest stiffening that lifts the modes a
// model leaves soft.
//
// The smallest generalised eigenvalue of (K_model, K_ref) on a support is the minimum over
// displacements v of the Rayleigh quotient v^T K_model v / v^T K_ref v, and K_model is linear
// in the stiffness k: lambda_min(k) is concave, and along a mode v (K_model v = lambda K_ref v)
// its derivative in k_e is delta_e(v)^2 / v^T K_ref v >= 0, delta_e(v) the elongation of spring
// e under v. So each round takes the modes below `target` on every user support (Lanczos' Ritz
// vectors, probe_evaluation.h) and the smallest change of the present springs, in the fit's
// scaled variables (sum (dk_e / s_e)^2), whose linear prediction lifts each to `target`:
//   minimise sum (dk_e / s_e)^2  subject to  lambda_j + a_j . dk >= target for every mode j,
// whose solution is dk = S^2 A^T mu, mu >= 0 the solution of the modes' small dual (a convex
// quadratic over mu >= 0, quadratic_nnls.h); dk >= 0 since A >= 0. Concavity makes the
// prediction optimistic, so the rounds repeat on the new modes. Only present springs change:
// the spring count, and a spring budget with it, stay as they were.
//
// Where the soft-mode refits (step 3) lift a mode by fitting the load along it, which moves
// every spring and lets another mode sink, this moves only the springs the soft modes stretch,
// by the least that lifts them.
#pragma once

#include <string>
#include <vector>

#include "engine/probe_fit/probe_bank.h"
#include "engine/problem/support_system.h"
#include "engine/runtime/interruption.h"

namespace springfit::response {

struct ModeLiftOptions {
  // The eigenvalue the soft modes are lifted to (> 0): a little above the fit's min_lambda, as
  // the linear prediction overshoots.
  double target = 0.12;
  // Rounds at most (>= 1), and modes per user support and round (>= 1).
  int rounds = 8;
  int modes_per_support = 8;
  void Validate(const std::string& owner = "ModeLiftOptions") const;
};

struct ModeLift {
  std::vector<double> weights;  // per gene
  int rounds = 0;               // run
  int modes = 0;                // lifted, summed over the rounds
};

// `weights` lifted; `scale` per gene (the fit's scaled variables, ProbeObjective::scale);
// `references` the reference factorised on each user support (index into bank.supports, the
// system). Throws Interrupted when stopped.
ModeLift LiftSoftModes(const Problem& problem, const std::vector<double>& weights,
                       const Vector& scale,
                       const std::vector<std::pair<int, SupportSystem>>& references,
                       const ModeLiftOptions& options, Interruption* interruption = nullptr);

}  // namespace springfit::response
