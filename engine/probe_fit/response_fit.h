// The probe fit: per-spring stiffness fitted to the reference's whole response at rest, not
// to the named load cases alone (docs/ARCHITECTURE.md, "The probe fit").
//
// Steps, each judged on probes no fit sees:
//  1. Probe bank (probe_bank.h): the named cases and generated loads on several supports,
//     split into fitted, choosing and held-out parts.
//  2. The fit (matrix_free_fit.h): projected Gauss-Newton on the exact (linear) error of the
//     fitted probes from the prior (the closed-form baseline), a few steps at each strength of
//     the Tikhonov pull toward it in `regularizations` (strongest first), with every soft mode
//     its models meet held by a penalty (mode_cuts.h); the iterate that does best on the
//     choosing probes is returned (early stopping). With a spring budget, sparsity paths down
//     to it. Springs the fit leaves below `dust` of the median stiffness are never part of a
//     model. At every choice a model that supports every mode (min_lambda) is preferred when
//     nearly as good (lambda_slack).
//  3. Soft modes: a model that still leaves a mode of a user support below min_lambda is fitted
//     again with the load along that mode (K_ref v, v the generalised eigenvector of the
//     smallest eigenvalue: the reference moves by v, the model by v / lambda_min) among the
//     fitted probes, family "mode" (up to `soft_modes_per_round` modes per support), at most
//     `soft_mode_rounds` times; the rounds' models are chosen among as the iterates are.
//  4. Mode lift (mode_lift.h): when the chosen model still leaves a mode below min_lambda, the
//     smallest stiffening of its present springs that lifts the soft modes is one more
//     candidate, chosen among with the others (its springs are the same).
// The model is the rest-linear one; a nonlinear reference's model describes its small-load
// limit.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/api/probe_fit_report.h"
#include "engine/probe_fit/mode_cuts.h"
#include "engine/probe_fit/mode_lift.h"
#include "engine/probe_fit/nonlinear_response.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/worker_pool.h"

namespace springfit::response {

struct ResponseFitOptions {
  ProbeOptions probes;
  // The Tikhonov strengths tried: moving every spring by its own prior stiffness costs as much
  // as a mean squared relative error of this. Each >= 0. With the held modes the weak pulls
  // no longer leave a mode soft, so the continuation runs down to 1e-6, where the choosing
  // errors are lower with every mode held (bench/RESULTS.md, "Held modes").
  std::vector<double> regularizations = {1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0};
  // Of the present springs removed per point of a budget's sparsity path, in (0, 1).
  double prune_fraction = 0.1;
  // Weights below this fraction of the median weight are removed (0 <= value < 1).
  double dust = 1e-6;
  // A bound on the model's stiffness spread, largest over smallest (> 1), asked by the user
  // (search.max_spread): in every model the fit considers, springs below the largest / this
  // leave it, as dust does. 0: none. A simulator's stiffest spring sets its stable time step,
  // and springs far below it carry nothing it would notice.
  double max_spread = 0.0;
  // Every mode supported: a model whose smallest generalised eigenvalue of (K_model, K_ref) on
  // a user support is below `min_lambda` leaves a mode soft that some load on that support
  // finds (probe_evaluation.h). Wherever a choice is made (the strength, the budget point, the
  // Gauss-Newton iterate), a model that reaches it is preferred when its choosing error is
  // within `lambda_slack` of the best. In [0, 1) and >= 0.
  double min_lambda = 0.1;
  double lambda_slack = 0.1;
  // A spring budget (> 0): the sparsity paths run down to it, and the returned model is the
  // one with the lowest choosing error within it (every mode held preferred); when no iterate
  // within it is a model, the one chosen as without a budget (the verdict then says the budget
  // is not met). 0: none.
  int max_springs = 0;
  // Refits that add the loads along soft modes (step 3), at most (>= 0; 0: none); and the modes
  // below min_lambda added per user support and refit, at most (>= 1). Each refit is a whole
  // fit, about doubling the run where it happens (bench/RESULTS.md, "Held modes"); with a
  // larger mode share a second refit lowered the fine kidney's lambda_min again.
  int soft_mode_rounds = 1;
  int soft_modes_per_round = 4;
  // Held modes (mode_cuts.h): the matrix-free fit's penalty on the modes its models left soft
  // (weight 0: none; then steps 3 and 4 alone hold them).
  ModeHoldOptions hold;
  // Step 4: whether to lift the modes a chosen model leaves below min_lambda, and how.
  bool lift_soft_modes = true;
  ModeLiftOptions lift;
  // The fit: Gauss-Newton steps per strength (>= 1); conjugate-gradient iterations
  // per step (>= 1) and their relative residual (in (0, 1)); random vectors per support that
  // estimate the preconditioner (>= 1).
  int steps_per_strength = 3;
  int cg_iterations = 20;
  double cg_tolerance = 0.1;
  int diagonal_samples = 16;
  // The matrix-free continuation ends after this many successive strengths whose models are
  // each worse on the choosing probes than the best before them (>= 0; 0: every strength runs).
  // On the largest block the strongest pull was the best and every weaker one worse, so the
  // patience saves most of the fit's time there; with the tool pushes fitted, the kidney's
  // choosing error rose for two strengths in a row before its best, so a patience of 2 stopped
  // short of it (bench/RESULTS.md, "Round seven").
  int continuation_patience = 3;

  void Validate(const std::string& owner = "ResponseFitOptions") const;
};

// Progress: called with the phase ("probe_fit", "probe_path", "probe_lift") and the best
// choosing error so far.
using ResponseProgress = std::function<void(const char* phase, double error)>;

// `prior` and the returned weights are per gene; `prior` > 0 somewhere. Throws Interrupted
// when `interruption` stops it. With a pool, the supports' factorisations and solves run in
// parallel; the result does not depend on the threads.
ResponseFitResult FitResponse(const Problem& problem, const ProbeBank& bank,
                              const SparseMatrix& reference_stiffness,
                              const std::vector<double>& prior, const ResponseFitOptions& options,
                              Interruption* interruption = nullptr,
                              const ResponseProgress& progress = {}, WorkerPool* pool = nullptr);

}  // namespace springfit::response
