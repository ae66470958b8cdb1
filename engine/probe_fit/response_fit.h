// The probe fit: per-spring stiffness fitted to the reference's whole response at rest, not
// to the named load cases alone (docs/ARCHITECTURE.md, "The probe fit").
//
// Steps, each judged on probes no fit sees:
//  1. Probe bank (probe_bank.h): the named cases and generated loads on several supports,
//     split into fitted, choosing and held-out parts.
//  2. The fit, one of two:
//   - matrix-free (matrix_free_fit.h, the default): projected Gauss-Newton on the exact
//     (linear) error of the fitted probes from the prior (the closed-form baseline), a few steps
//     at each strength of the Tikhonov pull toward it in `regularizations` (strongest first),
//     with every soft mode its models meet held by a penalty (mode_cuts.h); the iterate that
//     does best on the choosing probes is returned (early stopping);
//   - dense (up to `dense_max_genes` genes, 0 by default):
//     a. first-order fit (compliance_gram.h): the error of the model's displacement under the
//        fitted probes, to first order in K(k) - K_ref, is a convex quadratic in k; minimised
//        over k >= 0 (quadratic_nnls.h) at each strength (strongest first, each started from
//        the last), in variables scaled by the prior so the result does not depend on units.
//        The strength whose model does best on the choosing probes is kept.
//     b. sparsity path: the springs whose removal raises the quadratic least (saliency
//        1/2 k_e^2 H_ee) are removed, `prune_fraction` at a time, and the rest refitted; each
//        point is judged on the choosing probes, and the fewest springs within `tolerance` of
//        the best is kept.
//     c. Gauss-Newton refinement of the exact error over the kept springs, early stopped as
//        above.
//   Springs the fit leaves below `dust` of the median stiffness are never part of a model. At
//   every choice a model that supports every mode (min_lambda) is preferred when nearly as
//   good (lambda_slack).
//  5. Soft modes: a model that still leaves a mode of a user support below min_lambda is fitted
//     again with the load along that mode (K_ref v, v the generalised eigenvector of the
//     smallest eigenvalue: the reference moves by v, the model by v / lambda_min) among the
//     fitted probes, family "mode" (up to `soft_modes_per_round` modes per support), at most
//     `soft_mode_rounds` times; the rounds' models are
//     chosen among as the points of the path are.
//  6. Mode lift (mode_lift.h): when the chosen model still leaves a mode below min_lambda, the
//     smallest stiffening of its present springs that lifts the soft modes is one more
//     candidate, chosen among with the others (its springs are the same).
// The model is the rest-linear one; a nonlinear reference's model describes its small-load
// limit.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/probe_fit/mode_cuts.h"
#include "engine/probe_fit/mode_lift.h"
#include "engine/probe_fit/nonlinear_response.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_fit_report.h"
#include "engine/probe_fit/quadratic_nnls.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/worker_pool.h"

namespace springfit::response {

struct ResponseFitOptions {
  ProbeOptions probes;
  // The Tikhonov strengths tried: moving every spring by its own prior stiffness costs as much
  // as a mean squared relative error of this. Each >= 0. With the held modes the weak pulls
  // no longer leave a mode soft, and the fine kidney's choosing error fell from 0.058 at 1e-4
  // to 0.049 down to 1e-6, every mode held (bench/RESULTS.md, "Held modes").
  std::vector<double> regularizations = {1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0};
  // Of the present springs per path point, in (0, 1): the dense fit's sparsity path and the
  // matrix-free fit's budget paths.
  double prune_fraction = 0.1;
  // The dense fit's path (dense_max_genes), to the tolerance below: a removal that multiplies
  // the choosing error by more than this is retried with half as many springs (> 1), at most
  // `max_retries` times per point.
  double max_error_growth = 1.3;
  int max_retries = 3;
  int max_path_points = 60;  // >= 1
  // The path ends once the choosing probes' error passes this many times its best (> 1).
  double stop_error_factor = 1.5;
  // The returned point: the fewest springs within (1 + tolerance) of the best choosing error.
  double tolerance = 0.02;
  // Weights below this fraction of the median weight are removed (0 <= value < 1).
  double dust = 1e-6;
  // A bound on the model's stiffness spread, largest over smallest (> 1), asked by the user
  // (search.max_spread): in every model the fit considers, springs below the largest / this
  // leave it, as dust does. 0: none. A simulator's stiffest spring sets its stable time step,
  // and springs far below it carry nothing it would notice.
  double max_spread = 0.0;
  // The dense fit's Gauss-Newton steps at most (>= 0); they end earlier after three without a
  // better choosing error.
  int gauss_newton_steps = 20;
  // Every mode supported: a model whose smallest generalised eigenvalue of (K_model, K_ref) on
  // a user support is below `min_lambda` leaves a mode soft that some load on that support
  // finds (probe_evaluation.h). Wherever a choice is made (the strength, the path point, the
  // Gauss-Newton iterate), a model that reaches it is preferred when its choosing error is
  // within `lambda_slack` of the best. In [0, 1) and >= 0.
  double min_lambda = 0.1;
  double lambda_slack = 0.1;
  // A spring budget (> 0): the path runs at least down to it, and the returned point is the
  // one with the lowest choosing error within it among the models (every mode held); when no
  // point within it is one, the point chosen as without a budget (the verdict then says the
  // budget is not met). 0: none.
  int max_springs = 0;
  // Refits that add the loads along soft modes (step 5), at most (>= 0; 0: none); and the modes
  // below min_lambda added per user support and refit, at most (>= 1). Each refit is a whole
  // fit, about doubling the run where it happens (bench/RESULTS.md, "Held modes"); with a
  // larger mode share a second refit lowered the fine kidney's lambda_min again.
  int soft_mode_rounds = 1;
  int soft_modes_per_round = 4;
  // Held modes (mode_cuts.h): the matrix-free fit's penalty on the modes its models left soft
  // (weight 0: none; then steps 5 and 6 alone hold them).
  ModeHoldOptions hold;
  // Step 6: whether to lift the modes a chosen model leaves below min_lambda, and how.
  bool lift_soft_modes = true;
  ModeLiftOptions lift;
  QuadraticNnlsOptions nnls;
  // Up to this many genes the fit runs with a Gram matrix (the dense fit of step 2; 0: never, the
  // default): the matrix-free fit (matrix_free_fit.h) runs otherwise. The dense fit's memory is
  // m^2 doubles and each of its Newton steps m^3 / 3 (>= 0). Since the held modes
  // (mode_cuts.h) the matrix-free fit does better on the independent evaluator's every family
  // on the kidney too, where the dense fit's sparsity path gives a third fewer springs, and is
  // ten times faster on the fine kidney (bench/RESULTS.md, "Held modes").
  int dense_max_genes = 0;
  // The matrix-free fit: Gauss-Newton steps per strength (>= 1); conjugate-gradient iterations
  // per step (>= 1) and their relative residual (in (0, 1)); random vectors per support that
  // estimate the preconditioner (>= 1).
  int steps_per_strength = 3;
  int cg_iterations = 20;
  double cg_tolerance = 0.1;
  int diagonal_samples = 16;
  // The matrix-free continuation ends after this many successive strengths whose models are
  // each worse on the choosing probes than the best before them (>= 0; 0: every strength runs).
  // Each strength is a third of the fit's time; on the 10,582-node block the strongest pull was
  // the best and the four weaker ones were each worse (bench/RESULTS.md). With the tool pushes
  // fitted, the kidney's choosing error rose for two strengths in a row (1e-3, 1e-4) before its
  // best (1e-5): 2 stopped there with the named cases' E at 0.081 where 3 reaches 0.056.
  int continuation_patience = 3;

  void Validate(const std::string& owner = "ResponseFitOptions") const;
};

// Progress: called with the phase ("probe_fit", "probe_path", "probe_refine") and the best
// choosing error so far.
using ResponseProgress = std::function<void(const char* phase, double error)>;

// `prior` and the returned weights are per gene; `prior` > 0 somewhere. Throws Interrupted
// when `interruption` stops it. With a pool, each support's compliance, factorisation and
// part of the Gram matrices are computed in parallel; the result does not depend on the
// threads.
ResponseFitResult FitResponse(const Problem& problem, const ProbeBank& bank,
                              const SparseMatrix& reference_stiffness,
                              const std::vector<double>& prior, const ResponseFitOptions& options,
                              Interruption* interruption = nullptr,
                              const ResponseProgress& progress = {}, WorkerPool* pool = nullptr);

}  // namespace springfit::response
