#include "engine/fit/sparsity_path.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "engine/fit/pruning_path.h"
#include "engine/problem/cost.h"
#include "engine/runtime/options_check.h"

namespace springfit {
namespace {

PathPoint PointOf(const StiffnessFitResult& fit) {
  return PathPoint{PresentSprings(fit.weights), fit.normalized_error, fit.weights};
}

// The path after step 1 as the one pruning path's model (pruning_path.h): the named-case fit's
// saliencies order the springs, and each removal is a refit of the springs left, a point of
// the path.
class NamedCasePruning : public PrunableModel {
 public:
  NamedCasePruning(const Problem& problem, const std::vector<double>& start,
                   const std::vector<bool>& usable, const SparsityPathOptions& options,
                   const StiffnessFitOptions& first, const FitContext& context,
                   const PathProgress& progress, SparsityPath& path)
      : problem_(problem),
        start_(start),
        options_(options),
        progress_(progress),
        path_(path),
        current_(path.fit) {
    quiet_ = context;  // the refits report no steps
    quiet_.on_step = nullptr;
    refit_ = first;
    refit_.descent.max_steps = options.refit_iterations;
    // Along the path only the springs present may be refitted: the model shrinks at every
    // point (absent candidates had their chance, by their gradient, in step 1).
    allowed_.resize(usable.size());
    for (std::size_t g = 0; g < usable.size(); ++g)
      allowed_[g] = usable[g] && path.fit.weights[g] > 0.0;
  }

  int PresentSprings() const override { return path_.points.back().springs; }

  // Least leaned on first: the fit's saliencies (StiffnessFitResult::importance).
  std::vector<int> BySaliency() const override {
    std::vector<int> present;
    for (int g = 0; g < static_cast<int>(current_.weights.size()); ++g) {
      if (current_.weights[g] > 0.0) present.push_back(g);
    }
    std::stable_sort(present.begin(), present.end(),
                     [&](int a, int b) { return current_.importance[a] < current_.importance[b]; });
    return present;
  }

  // Refits without `genes`. With `may_refuse`, a removal that multiplies the error by more
  // than `max_error_growth` is too costly (the saliencies are first-order: many springs at
  // once can matter together).
  Removal Remove(const std::vector<int>& genes, bool may_refuse) override {
    std::vector<bool> trial_allowed = allowed_;
    std::vector<double> trial_start = current_.weights;
    for (int g : genes) {
      trial_allowed[g] = false;
      trial_start[g] = 0.0;
    }
    StiffnessFitResult fit =
        FitStiffness(problem_, trial_start, FitScope{trial_allowed, {}, start_}, refit_, quiet_);
    path_.solves += fit.solves;
    path_.steps += fit.iterations;
    if (fit.interrupted) throw Interrupted();  // a half-done refit is not a path point
    if (!fit.feasible) return Removal::kInfeasible;
    const double max_growth2 = options_.max_error_growth * options_.max_error_growth;
    if (may_refuse && fit.normalized_error > max_growth2 * path_.points.back().normalized_error)
      return Removal::kTooCostly;
    current_ = std::move(fit);
    for (std::size_t g = 0; g < allowed_.size(); ++g)
      allowed_[g] = trial_allowed[g] && current_.weights[g] > 0.0;
    path_.points.push_back(PointOf(current_));
    if (progress_) progress_(path_);
    return Removal::kAccepted;
  }

 private:
  const Problem& problem_;
  const std::vector<double>& start_;
  const SparsityPathOptions& options_;
  const PathProgress& progress_;
  SparsityPath& path_;
  FitContext quiet_;
  StiffnessFitOptions refit_;
  StiffnessFitResult current_;
  std::vector<bool> allowed_;
};

}  // namespace

void SparsityPathOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  fit.Validate(check.Nested("fit"));
  check.Require(refit_iterations >= 1, "refit_iterations", refit_iterations, "value >= 1");
  check.Require(InOpenUnit(prune_fraction), "prune_fraction", prune_fraction, "0 < value < 1");
  check.Require(tolerance >= 0.0 && std::isfinite(tolerance), "tolerance", tolerance,
                "0 <= value < infinity");
  check.Require(max_points >= 1, "max_points", max_points, "value >= 1");
  check.Require(stop_error_factor > 1.0 && std::isfinite(stop_error_factor), "stop_error_factor",
                stop_error_factor, "1 < value < infinity");
  check.Require(max_retries >= 0, "max_retries", max_retries, "value >= 0");
  check.Require(held_out_iterations >= 1, "held_out_iterations", held_out_iterations, "value >= 1");
  check.Require(max_error_growth > 1.0 && std::isfinite(max_error_growth), "max_error_growth",
                max_error_growth, "1 < value < infinity");
}

SparsityPath TraceSparsityPath(const Problem& problem, const std::vector<double>& start,
                               const std::vector<bool>& usable, const SparsityPathOptions& options,
                               double stop_normalized_error, int min_springs,
                               const FitContext& context, const PathProgress& progress) {
  options.Validate();
  SparsityPath path;
  // One bound for every fit of the path (a refit's own start would raise it each time).
  path.upper_bound =
      options.fit.upper_bound > 0.0
          ? options.fit.upper_bound
          : options.fit.max_stiffness_ratio * *std::max_element(start.begin(), start.end());
  StiffnessFitOptions first = options.fit;
  first.upper_bound = path.upper_bound;
  path.fit = FitStiffness(problem, start, FitScope{usable, {}, {}}, first, context);
  path.solves = path.fit.solves;
  path.steps = path.fit.iterations;
  if (!path.fit.feasible) return path;
  path.points.push_back(PointOf(path.fit));
  if (path.fit.interrupted) {
    path.interrupted = true;
    return path;
  }
  const double stop =
      std::max(stop_normalized_error,
               options.stop_error_factor * options.stop_error_factor * path.fit.normalized_error);
  NamedCasePruning model(problem, start, usable, options, first, context, progress, path);
  PruningOptions pruning;
  pruning.prune_fraction = options.prune_fraction;
  pruning.max_refusals = options.max_retries;
  // (A removal refused once can pass later: a nonlinear model's solves depend on the stiffness
  // the refits changed.)
  pruning.retry_kept = true;
  try {
    if (progress) progress(path);  // (its stop request stops the path: the fit's point stands)
    PruneModel(model, min_springs, pruning, [&] {
      return static_cast<int>(path.points.size()) < options.max_points &&
             !(path.points.back().normalized_error > stop);
    });
  } catch (const Interrupted&) {
    path.interrupted = true;  // the path so far stands (it has the fit's point)
  }
  return path;
}

std::optional<HeldOutError> HeldOutErrors(const Problem& problem,
                                          const std::vector<double>& weights,
                                          const std::vector<double>& start,
                                          const SparsityPathOptions& path_options,
                                          const FitContext& context) {
  const std::size_t cases = problem.load_cases().size();
  StiffnessFitOptions options = path_options.fit;
  options.descent.max_steps = path_options.held_out_iterations;
  options.saliency_probes = 0;
  if (cases < 2) return std::nullopt;
  std::vector<bool> support(weights.size());
  for (std::size_t g = 0; g < weights.size(); ++g) support[g] = weights[g] > 0.0;
  // Every spring of the model present at the start (those the start lacks at its typical
  // stiffness): under the linear response whether a model is a mechanism depends on its
  // springs alone, so the model's equilibria make the start's.
  std::vector<double> fold_start(weights.size(), 0.0);
  const double typical = MedianPositive(start);
  for (std::size_t g = 0; g < weights.size(); ++g) {
    if (support[g]) fold_start[g] = g < start.size() && start[g] > 0.0 ? start[g] : typical;
  }
  CostOptions cost_options;
  cost_options.solve_cases_of_mechanisms = true;  // judge case k whatever the others say
  CostFunction cost(problem, cost_options);
  cost.set_interruption(context.interruption);
  FitContext quiet = context;
  quiet.on_step = nullptr;
  HeldOutError out;
  double numerator = 0.0, denominator = 0.0;
  for (std::size_t k = 0; k < cases; ++k) {
    std::vector<bool> fitted(cases, true);
    fitted[k] = false;
    const StiffnessFitResult fit =
        FitStiffness(problem, fold_start, FitScope{support, fitted, start}, options, quiet);
    if (fit.interrupted) throw Interrupted();
    const Evaluation e = cost.Evaluate(problem.SpringsOfWeights(fit.weights));
    if (e.interrupted) throw Interrupted();
    const PreparedLoadCase& lc = problem.load_cases()[k];
    // (A case that moves no free node is normalised by the whole reference, as in
    // engine/problem/cost.h, and adds nothing to the total's denominator: its error counts in the
    // numerator only.)
    const double norm2 = lc.reference_norm2 > 0.0 ? lc.reference_norm2 : problem.reference_norm2();
    const LoadCaseEvaluation& judged = e.load_cases[k];
    const double case_cost =
        judged.solve.converged() ? judged.cost : std::numeric_limits<double>::infinity();
    out.per_case.push_back(case_cost / norm2);
    numerator += case_cost;
    denominator += lc.reference_norm2;
  }
  out.normalized_error = numerator / denominator;
  return out;
}

std::optional<RegularizationChoice> ChooseRegularization(const Problem& problem,
                                                         const std::vector<double>& start,
                                                         const std::vector<bool>& usable,
                                                         const SparsityPathOptions& options,
                                                         const FitContext& context) {
  std::vector<double> every(start.size(), 0.0);
  for (std::size_t g = 0; g < start.size(); ++g) every[g] = usable[g] ? 1.0 : 0.0;
  RegularizationChoice choice;
  double lowest = std::numeric_limits<double>::infinity();
  for (const double strength : kRegularizationChoices) {
    SparsityPathOptions regularised = options;
    regularised.fit.regularization = strength;
    const auto held_out = HeldOutErrors(problem, every, start, regularised, context);
    if (!held_out) return std::nullopt;
    choice.strengths.push_back(strength);
    choice.held_out_normalized_errors.push_back(held_out->normalized_error);
    if (held_out->normalized_error < lowest) {
      lowest = held_out->normalized_error;
      choice.chosen = strength;
    }
  }
  return choice;
}

std::size_t SelectPathPoint(const SparsityPath& path, int max_springs,
                            double target_normalized_error, double tolerance) {
  const std::vector<PathPoint>& points = path.points;
  std::size_t lowest = 0, smallest = 0;
  for (std::size_t i = 1; i < points.size(); ++i) {
    if (points[i].normalized_error < points[lowest].normalized_error) lowest = i;
    if (points[i].springs < points[smallest].springs) smallest = i;
  }
  // The fewest springs among the points that satisfy `ok`, or `fallback` when none does.
  const auto fewest = [&](auto ok, std::size_t fallback) {
    std::size_t best = points.size();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (ok(points[i]) && (best == points.size() || points[i].springs < points[best].springs))
        best = i;
    }
    return best == points.size() ? fallback : best;
  };
  if (max_springs > 0) {
    std::size_t best = points.size();
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (points[i].springs <= max_springs &&
          (best == points.size() || points[i].normalized_error < points[best].normalized_error))
        best = i;
    }
    return best == points.size() ? smallest : best;
  }
  if (target_normalized_error > 0.0) {
    return fewest([&](const PathPoint& p) { return p.normalized_error <= target_normalized_error; },
                  lowest);
  }
  const double bound = std::pow(1.0 + tolerance, 2) * points[lowest].normalized_error;
  return fewest([&](const PathPoint& p) { return p.normalized_error <= bound; }, lowest);
}

}  // namespace springfit
