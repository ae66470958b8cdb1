// Per-spring stiffness (k >= 0) on a candidate set, fitted to the reference's displacements:
//   f(w) = 1/2 sum_k sum_i |u^M_ik(w) - u^R_ik|^2,   0 <= w <= w_max,
// over load cases k and free nodes i, u^M the model's response (linear or nonlinear, as the
// problem's solver options say). A weight that reaches 0 has left the model; one whose
// gradient points back in returns, so the gradient ranks every absent candidate in one pass.
//
// Sparse throughout, with no dense Jacobian and no cap on the genes. The Jacobian
// J = du/dw is only ever applied: per load case, the equilibrium's tangent H gives
// du/dw_j = H^-1 a_j, a_j the force spring j exerts per unit stiffness (the force balance's
// column, engine/problem/force_balance.h), so
//   J v   = H^-1 (A v)       one solve per load case,
//   J^T y = A^T (H^-1 y)     one solve per load case (H symmetric): the adjoint; J^T r is the
//                            gradient for every spring at the price of one solve per case.
// Each step is the fitting core's (gauss_newton.h) in its trust region: a projected
// Gauss-Newton step by Steihaug's truncated conjugate gradients on J^T J (weights at a bound
// whose gradient pushes them out held there), in variables scaled by the weights themselves,
// so that a step's size is relative to the stiffness it changes and the result does not depend
// on the units.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/fit/gauss_newton.h"
#include "engine/genome/gene_weights.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/worker_pool.h"

namespace springfit {

// The named-case fit's descent on the core (its defaults): 200 steps tried, accepted or not;
// 40 conjugate-gradient iterations per step (2 solves per case each), stopped at 1e-3 of the
// initial residual; the trust region from 1 (weights change by 100%) up to 1e3 in the scaled
// units (the bounds, 0 and upper_bound, keep weights out of the rigid and mechanism limits;
// the largest radius only keeps a step finite); converged when two accepted steps in a row
// lower f by less than 1e-6 of it. Its target_value is the fit's own (an exact fit, E 1e-12).
GaussNewtonOptions NamedCaseDescent();

struct StiffnessFitOptions {
  GaussNewtonOptions descent = NamedCaseDescent();  // a trust region: initial_radius > 0
  // Step scaling: weight j moves in units of max(w_j, scale_floor * median positive weight),
  // so that an absent spring can enter at a typical stiffness.
  double scale_floor = 0.1;
  // Random-sign products that estimate the saliencies' Jacobian column norms (one solve per
  // load case each, once per fit); 0: no saliency (`importance` empty), for fits whose caller
  // does not prune.
  int saliency_probes = 16;
  // The weights' upper bound; 0: max_stiffness_ratio times the start's largest weight. A
  // sequence of fits (the sparsity path, its refits) passes its first fit's bound, or the
  // bound would grow by that ratio with every fit.
  double upper_bound = 0.0;
  // Weights are bounded above by this times the largest weight of the start: beyond, a spring
  // is rigid for the data and the displacements stop responding to it.
  double max_stiffness_ratio = 1e4;
  // Tikhonov regularisation toward the prior (FitScope::prior): the fit minimises
  //   E^2 + regularization x mean_j ((w_j - p_j) / s_j)^2,
  // s_j = max(p_j, scale_floor x the prior's median positive weight), the mean over every
  // gene. Dimensionless: 0.01 means that moving every spring by its own prior stiffness costs
  // as much as E^2 = 0.01. It trades fit on the load cases seen for fit on those not seen
  // (the closed-form prior knows the material is isotropic); its strength is chosen by the
  // held-out error (sparsity_path.h, ChooseRegularization). 0: none.
  double regularization = 0.0;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate(const std::string& owner = "StiffnessFitOptions") const;
};

struct StiffnessFitResult {
  std::vector<double> weights;  // per gene, >= 0 (0 = absent)
  bool feasible = true;         // false: the start has no equilibrium; weights are the start
  // sum |u^M - u^R|^2 / sum |u^R|^2 over the fitted cases, at the result (the data alone,
  // without the regularisation's term)
  double normalized_error = 0.0;
  double initial_normalized_error = 0.0;  // at the start
  int iterations = 0;                     // steps tried
  int accepted = 0;                       // steps accepted
  std::int64_t solves = 0;                // tangent solves (back-substitutions)
  bool converged = false;  // stopped by the tolerance rather than the iteration limit
  // Stopped by the Interruption after the start's evaluation: `weights` are the last accepted
  // step's (a model with an equilibrium in every fitted case), `importance` is empty.
  bool interrupted = false;
  // Per gene, at the result: its saliency 1/2 w_j^2 |J e_j|^2, about how much f would rise
  // without spring j (optimal brain damage), |J e_j| estimated by random probes.
  std::vector<double> importance;
};

// After every accepted step: the weights and their normalised error (over the fitted cases).
using FitStepCallback = std::function<void(const std::vector<double>& weights,
                                           double normalized_error, int accepted_steps)>;

// What a fit sees: `usable[g]` false holds gene g at 0; `cases[k]` false leaves load case k
// out of f (empty: every case), to judge the model on it afterwards (cross-validation).
// `prior` is what the regularisation pulls toward (empty: the start).
struct FitScope {
  std::vector<bool> usable;
  std::vector<bool> cases;
  std::vector<double> prior;
};

// How a fit runs: where it checks for a stop, on which threads, whom it tells.
struct FitContext {
  // Checked inside every nonlinear solve, between load cases and between conjugate-gradient
  // iterations; with a pool, while the owner waits for the cases (nullptr: never).
  Interruption* interruption = nullptr;
  // The load cases' solves in parallel (nullptr: the calling thread alone). Each case has its
  // own state: the result does not depend on the threads.
  WorkerPool* pool = nullptr;
  FitStepCallback on_step;
};

// Stopped while the start is evaluated it throws Interrupted; later it returns the last
// accepted weights (`interrupted`).
StiffnessFitResult FitStiffness(const Problem& problem, const std::vector<double>& start,
                                const FitScope& scope, const StiffnessFitOptions& options = {},
                                const FitContext& context = {});

}  // namespace springfit
