// Strategy `continuous`: topology and per-spring stiffness by sensitivities, and the trade-off
// between a model's size and its error (issue 16).
//
// 1. Fit: every candidate gets a stiffness >= 0 by the continuous fit (stiffness_fit.h),
//    started from `start` (the closed-form baseline on an FEM reference's mesh edges, 0 on the
//    other candidates). Candidates enter by their gradient, which ranks all of them in one
//    adjoint pass; those the fit drives to 0 leave. The fit only ever accepts steps that lower
//    the error, so the result is at least as good as the start.
// 2. Path: the one pruning path (pruning_path.h) over this fit: the springs whose removal
//    raises the error least (the lowest saliency, StiffnessFitResult::importance) are removed,
//    `prune_fraction` of them at a time, and the rest refitted from where they were; each
//    refit is one point of the sparsity path (springs, E). A removal that would leave a
//    mechanism, or that multiplies E by more than `max_error_growth`, is retried with fewer
//    springs; a single spring whose removal leaves a mechanism is kept (it holds a mode no load
//    case loads) until every spring is so marked, when all are tried once more (a nonlinear
//    model's solves depend on the stiffness the refits changed). The path ends where a whole
//    round removes no spring, or where E passes the stop.
// 3. Choice (SelectPathPoint): the fewest springs whose E is within `tolerance` of the best
//    on the path, or the user's size or error target; then refitted to convergence.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/runtime/interruption.h"

namespace springfit {

struct SparsityPathOptions {
  StiffnessFitOptions fit;  // the first fit and the final one
  // Trust-region steps of each refit along the path (its points are then near-optimal; the
  // chosen one is refitted to convergence).
  int refit_iterations = 15;
  double prune_fraction = 0.1;  // of the present springs removed per path step, in (0, 1)
  // A removal of several springs that multiplies E by more than this is retried with half as
  // many (> 1), at most `max_retries` times per point (then the last try stands): each retry
  // is a refit.
  double max_error_growth = 1.5;
  int max_retries = 2;
  // Steps of each held-out fit (HeldOutErrors). Each starts from the start, not from the
  // model judged (whose weights have seen the case left out): fewer steps than a full fit
  // make the held-out error, if anything, pessimistic.
  int held_out_iterations = 50;
  // The path ends once E passes this many times the fit's E (> 1; a caller's size or error
  // target takes it further): far enough for the trade-off near the best models, which is
  // where the choice is made, without spending on models no one would pick.
  double stop_error_factor = 2.0;
  // The default choice: the fewest springs whose E <= (1 + tolerance) x the lowest E on the
  // path.
  double tolerance = 0.05;
  int max_points = 200;  // path points at most (the path is at most this long)

  void Validate(const std::string& owner = "SparsityPathOptions") const;
};

struct PathPoint {
  int springs = 0;
  double normalized_error = 0.0;  // e = E^2
  std::vector<double> weights;    // per gene
};

struct SparsityPath {
  StiffnessFitResult fit;         // step 1, on every usable candidate
  std::vector<PathPoint> points;  // points[0] is the fit's model; springs decrease
  std::int64_t solves = 0;        // tangent solves, fit and path
  int steps = 0;                  // trust-region steps, fit and path
  double upper_bound = 0.0;       // the stiffness bound of every fit of the path
  bool interrupted = false;
};

// Called after step 1 and after every path point, with the path so far.
using PathProgress = std::function<void(const SparsityPath&)>;

// Stops tracing when E passes max(sqrt(`stop_normalized_error`), `stop_error_factor` x the
// fit's E) (after recording that point) or the model reaches `min_springs` springs. `on_step`
// follows step 1's fit. Stopped by `interruption` while the start is evaluated it throws
// Interrupted; later it returns the path so far, `interrupted` set (stopped in step 1: its one
// point is the fit's last step).
SparsityPath TraceSparsityPath(const Problem& problem, const std::vector<double>& start,
                               const std::vector<bool>& usable, const SparsityPathOptions& options,
                               double stop_normalized_error, int min_springs,
                               const FitContext& context = {}, const PathProgress& progress = {});

// Cross-validation over the load cases: for each case k, the model's springs (the support of
// `weights`) fitted from `start` to the other cases, then judged on case k. Starting from
// `start` (the closed-form baseline), not from `weights`, keeps case k out of the fitted
// stiffness; only the choice of springs has seen it. Per case the normalised error
// sum |u - u^R|^2 / sum |u^R|^2 over case k's free nodes (infinity where the fitted model has no
// equilibrium in case k); nullopt with fewer than two cases. The fits take
// `options.held_out_iterations` steps of `options.fit` (no saliency). Throws Interrupted.
struct HeldOutError {
  std::vector<double> per_case;
  double normalized_error = 0.0;  // over all cases: sum of their errors' numerators / norms
};
std::optional<HeldOutError> HeldOutErrors(const Problem& problem,
                                          const std::vector<double>& weights,
                                          const std::vector<double>& start,
                                          const SparsityPathOptions& options,
                                          const FitContext& context = {});

// The regularisation strengths `search.regularization: auto` chooses among
// (StiffnessFitOptions::regularization): none, and pulls toward the start whose E^2 cost is
// 0.1%, 1% and 10% of the mean square relative change.
inline constexpr double kRegularizationChoices[] = {0.0, 1e-3, 1e-2, 1e-1};

// Each strength's held-out error: the fit on every usable candidate (all present at the
// start, those `start` lacks at its median), cross-validated over the load cases as in
// HeldOutErrors, regularised toward `start`. `chosen` is the strength with the lowest held-out
// error (the weaker on a tie). One fit per load case and strength: the dearest part of a run
// on a large scene. nullopt with fewer than two cases. Throws Interrupted.
struct RegularizationChoice {
  double chosen = 0.0;
  std::vector<double> strengths;
  std::vector<double> held_out_normalized_errors;  // per strength
};
std::optional<RegularizationChoice> ChooseRegularization(const Problem& problem,
                                                         const std::vector<double>& start,
                                                         const std::vector<bool>& usable,
                                                         const SparsityPathOptions& options,
                                                         const FitContext& context = {});

// The point to return: with `max_springs` > 0, the lowest E with at most that many springs
// (the smallest model when none has); else with `target_normalized_error` > 0, the fewest
// springs with e <= it (the lowest e when none has); else the fewest springs with
// E <= (1 + tolerance) x the lowest E. Precondition: the path has a point.
std::size_t SelectPathPoint(const SparsityPath& path, int max_springs,
                            double target_normalized_error, double tolerance);

}  // namespace springfit
