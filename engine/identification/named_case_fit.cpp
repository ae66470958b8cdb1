// Strategy continuous fitted to the named load cases (no probes: a positions reference,
// `--probes none`, or a target error): the sparsity path from the start, the chosen point
// refitted, the final evaluation's next in line, the load cases' cross-validation, and, where
// the reference can be probed, the certificate on the probe bank with the baseline guarantee.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "engine/fit/sparsity_path.h"
#include "engine/identification/strategy.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/cost.h"

namespace springfit {
namespace {

// One run of the fit, step by step; Run() reads as the method.
class NamedCaseFit {
 public:
  NamedCaseFit(const Problem& problem, const SearchOptions& options, const RunContext& context,
               RunMonitor& monitor)
      : problem_(problem),
        options_(options),
        context_(context),
        monitor_(monitor),
        genes_(problem.gene_count()),
        target_(options.target_error * options.target_error),
        start_time_(std::chrono::steady_clock::now()),
        pool_(PoolOf(context, own_pool_)),
        quiet_{&monitor.interruption(), pool_, {}},
        usable_(static_cast<std::size_t>(genes_), true) {
    r_.options = options;  // (RunIdentification sets identify: continuous identifies stiffness)
    r_.trace = context.trace;
  }

  IdentificationResult Run() {
    ChooseStart();
    ChooseStrength();
    TracePath();
    RefitChosenPoint();
    EvaluateFinally();
    CrossValidate();
    Record();
    r_.stop_message = Message();
    CertifyOnProbeBank();
    r_.continuous = std::move(details_);
    return std::move(r_);
  }

 private:
  // The start: the closed-form baseline where it is a model of the candidates, else the
  // training stiffness on every candidate.
  void ChooseStart() {
    if (problem_.scene().reference.kind == Reference::Kind::kFem)
      start_ = BaselineGeneWeights(problem_);
    details_.started_from_baseline = start_.has_value();
    if (!start_) start_ = TrainingStart();
  }
  std::vector<double> TrainingStart() const {
    return std::vector<double>(static_cast<std::size_t>(genes_), problem_.training_stiffness());
  }

  // The regularisation: the setting's, or the one whose held-out error is lowest. A stop here
  // comes before any fit: the start is returned.
  void ChooseStrength() {
    path_options_.fit.regularization = options_.regularization;
    if (options_.choose_regularization) {
      ClockPhase(monitor_, "regularization");
      try {
        if (const auto choice =
                ChooseRegularization(problem_, *start_, usable_, path_options_, quiet_)) {
          path_options_.fit.regularization = choice->chosen;
          details_.regularization_strengths = choice->strengths;
          details_.regularization_held_out = choice->held_out_normalized_errors;
        }
      } catch (const Interrupted&) {
        stopped_choosing_ = true;
      }
    }
    details_.regularization = path_options_.fit.regularization;
  }

  // The path from the start (a size limit traces it at least that far), again from the
  // training stiffness when the baseline has no equilibrium (a nonlinear response at a large
  // load). Beats carry the error of the last accepted step; trace rows follow the first fit.
  void TracePath() {
    monitor_.SetPhase("fit", [this](ProgressBeat& beat) {
      beat.wall_seconds = SecondsSince(start_time_);
      beat.generation = static_cast<int>(r_.trace.size());
      beat.evaluations = fit_steps_;
      beat.best_normalized_error = current_error_;
    });
    const FitContext fit_context{
        &monitor_.interruption(), pool_,
        [this](const std::vector<double>& w, double e, int accepted) { OnStep(w, e, accepted); }};
    const PathProgress on_point = [this](const SparsityPath& path) { OnPoint(path); };
    const double stop =
        options_.max_springs > 0 ? std::numeric_limits<double>::infinity() : target_;
    if (!stopped_choosing_) {
      path_ = TraceSparsityPath(problem_, *start_, usable_, path_options_, stop,
                                options_.max_springs, fit_context, on_point);
    }
    if (path_.points.empty() && details_.started_from_baseline && !stopped_choosing_) {
      details_.started_from_baseline = false;
      start_ = TrainingStart();
      path_ = TraceSparsityPath(problem_, *start_, usable_, path_options_, stop,
                                options_.max_springs, fit_context, on_point);
    }
    details_.steps = path_.steps;
    details_.solves = path_.solves;
    stopped_ = path_.interrupted || cancelled_ || stopped_choosing_;
    weights_ = *start_;
  }

  // A trace row (and the caller's on_iteration) for a model; a refusal or the time limit
  // cancels the run.
  void Report(const std::vector<double>& weights, double normalized_error, int steps) {
    TraceRow row;
    row.generation = static_cast<int>(r_.trace.size());
    row.wall_seconds = SecondsSince(start_time_);
    row.evaluations = steps;
    row.best_normalized_error = normalized_error;
    row.best_cost = normalized_error * problem_.reference_norm2();
    row.mean_cost = row.best_cost;
    r_.trace.push_back(row);
    monitor_.Reported();
    if (monitor_.TimeLimitPassed()) cancelled_ = true;
    if (!context_.on_iteration) return;
    Genome best(static_cast<std::size_t>(genes_), 0);
    for (int g = 0; g < genes_; ++g) best[g] = weights[g] > 0.0;
    IterationState state;
    state.best = &best;
    if (!context_.on_iteration(row, state)) cancelled_ = true;
  }

  // The first fit's accepted steps: rows after steps 1, 2, 4, 8, ...
  void OnStep(const std::vector<double>& weights, double error, int accepted) {
    current_error_ = error;
    fit_steps_ = accepted;
    if (accepted == next_row_) {
      next_row_ *= 2;
      reported_steps_ = accepted;
      Report(weights, error, accepted);
      if (cancelled_) throw Interrupted();  // the fit returns its last accepted step
    }
  }

  // The path's points: the first ends the fit (its last row), and beats describe the path.
  void OnPoint(const SparsityPath& path) {
    if (path.points.size() == 1) {
      if (reported_steps_ != path.fit.accepted) {
        reported_steps_ = path.fit.accepted;
        Report(path.fit.weights, path.fit.normalized_error, path.fit.accepted);  // the fit's end
      }
      monitor_.SetPhase("path", [this](ProgressBeat& beat) {
        beat.wall_seconds = SecondsSince(start_time_);
        beat.generation = static_cast<int>(path_points_);
        beat.evaluations = fit_steps_;
        beat.best_normalized_error = path_error_;
      });
    }
    path_points_ = path.points.size();
    path_error_ = path.points.back().normalized_error;
    if (cancelled_) throw Interrupted();  // the path so far stands
  }

  // The point the rule chooses, refitted on its own springs (no pruning follows: no saliency).
  void RefitChosenPoint() {
    if (path_.points.empty()) return;
    for (const PathPoint& point : path_.points)
      details_.path.push_back({point.springs, point.normalized_error});
    details_.fit_normalized_error = path_.fit.normalized_error;
    details_.start_normalized_error = path_.fit.initial_normalized_error;
    returned_ = selected_ = static_cast<int>(
        SelectPathPoint(path_, options_.max_springs, target_, path_options_.tolerance));
    weights_ = path_.points[static_cast<std::size_t>(returned_)].weights;
    if (stopped_) return;
    try {
      ClockPhase(monitor_, "refit");
      std::vector<bool> support(weights_.size());
      for (std::size_t g = 0; g < weights_.size(); ++g) support[g] = weights_[g] > 0.0;
      StiffnessFitOptions refit_options = path_options_.fit;
      refit_options.upper_bound = path_.upper_bound;
      refit_options.saliency_probes = 0;
      const StiffnessFitResult refit =
          FitStiffness(problem_, weights_, FitScope{support, {}, *start_}, refit_options, quiet_);
      details_.steps += refit.iterations;
      details_.solves += refit.solves;
      if (refit.feasible) {
        weights_ = refit.weights;
        refitted_ = true;
      }
      stopped_ = refit.interrupted;
    } catch (const Interrupted&) {
      stopped_ = true;
    }
  }

  // The returned model is judged by the evaluation every strategy's is (each case solved from
  // the reference's equilibrium, engine/problem/cost.h). The fit's solves start from the last
  // step's equilibria, and a nonlinear model near a mechanism can have an equilibrium there that
  // Newton from the reference does not reach: a model without equilibrium in that evaluation,
  // or worse than the start, is not returned. The next in line are the chosen point as the
  // path left it, the other points by error, and the start (the baseline).
  void EvaluateFinally() {
    const std::vector<int> next_in_line = NextInLine();
    const auto acceptable = [&](const Evaluation& e) {
      return e.converged && !e.mechanism &&
             (path_.points.empty() ||
              e.normalized_error <= details_.start_normalized_error * (1.0 + 1e-9));
    };
    r_.evaluation = cost_.Evaluate(problem_.SpringsOfWeights(weights_));
    for (std::size_t i = 0; i < next_in_line.size() && !acceptable(r_.evaluation); ++i) {
      ++details_.rejected;
      returned_ = next_in_line[i];
      refitted_ = false;
      weights_ =
          returned_ >= 0 ? path_.points[static_cast<std::size_t>(returned_)].weights : *start_;
      r_.evaluation = cost_.Evaluate(problem_.SpringsOfWeights(weights_));
    }
    details_.chosen = returned_;
    details_.model_seconds = SecondsSince(start_time_);
  }

  // Path points and the start (-1), in the order the final evaluation tries them.
  std::vector<int> NextInLine() const {
    if (path_.points.empty()) return {-1};
    std::vector<int> next_in_line;
    for (int i = 0; i < static_cast<int>(path_.points.size()); ++i) next_in_line.push_back(i);
    std::stable_sort(next_in_line.begin(), next_in_line.end(), [&](int a, int b) {
      return path_.points[a].normalized_error < path_.points[b].normalized_error;
    });
    // A size limit is kept as long as some model meets it: those that do first (the start
    // among them when it does: the baseline on the mesh edges can be smaller than any path
    // point better than it).
    const int limit = options_.max_springs;
    const auto within = [&](int i) {
      return limit > 0 && (i >= 0 ? path_.points[static_cast<std::size_t>(i)].springs
                                  : PresentSprings(*start_)) <= limit;
    };
    auto end_within = std::stable_partition(next_in_line.begin(), next_in_line.end(), within);
    next_in_line.insert(within(-1) ? end_within : next_in_line.end(), -1);
    std::stable_partition(next_in_line.begin(), next_in_line.end(),
                          [&](int i) { return i == returned_; });
    if (!refitted_) next_in_line.erase(next_in_line.begin());  // (the point itself failed)
    return next_in_line;
  }

  // The returned model's generalisation: each load case predicted by its springs fitted to the
  // others.
  void CrossValidate() {
    if (stopped_ || path_.points.empty()) return;
    ClockPhase(monitor_, "held_out");
    try {
      if (const auto held_out = HeldOutErrors(problem_, weights_, *start_, path_options_, quiet_)) {
        details_.held_out_normalized_error = held_out->normalized_error;
        details_.held_out_per_case = held_out->per_case;
      }
    } catch (const Interrupted&) {
      stopped_ = true;
    }
  }

  // `model` as the result's genome and stiffness.
  void Take(const std::vector<double>& model) {
    r_.best.assign(static_cast<std::size_t>(genes_), 0);
    r_.stiffness.clear();
    for (int g = 0; g < genes_; ++g) {
      if (model[g] > 0.0) {
        r_.best[g] = 1;
        r_.stiffness.push_back(model[g]);  // gene order is candidate order
      }
    }
  }

  void Record() {
    Take(weights_);
    r_.counters.evaluations = details_.steps;
    r_.wall_seconds = SecondsSince(start_time_);
    const double e = r_.evaluation.normalized_error;
    r_.stop =
        stopped_ ? (monitor_.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled)
        : target_ > 0.0 && e <= target_ ? StopReason::kTargetReached
                                        : StopReason::kCompleted;
  }

  // The stop message: why there is no fit, or which point by which rule, and what came of it.
  std::string Message() const {
    const double e = r_.evaluation.normalized_error;
    if (stopped_choosing_)
      return fmt::format(
          "{} while the regularisation was chosen, before any fit: the start ({}) at E {:.3g}",
          r_.stop == StopReason::kTimeLimit ? "time limit reached" : "stopped on request",
          StartName(), std::sqrt(e));
    if (path_.points.empty())
      return fmt::format(
          "no model with an equilibrium in every load case to start from (the start is a "
          "mechanism or does not converge){}",
          problem_.response() == Response::kNonlinear
              ? ": try the linear response (search.response) or smaller loads"
              : ": try more candidates");
    const std::string refused =
        details_.rejected > 0
            ? fmt::format(
                  "; {} model(s) refused by the final evaluation (no equilibrium from "
                  "the reference's, or worse than the start)",
                  details_.rejected)
            : std::string();
    return fmt::format(
        "{}{} springs at E {:.3g}, from {}; the fit on every candidate reached E {:.3g} from "
        "{:.3g} at its start ({}){}",
        stopped_ ? (r_.stop == StopReason::kTimeLimit ? "time limit reached; the best so far: "
                                                      : "stopped on request; the best so far: ")
                 : "",
        PresentSprings(weights_), std::sqrt(e), ReturnedFrom(),
        std::sqrt(details_.fit_normalized_error), std::sqrt(details_.start_normalized_error),
        StartName(), refused);
  }

  const char* StartName() const {
    return details_.started_from_baseline ? "the closed-form baseline"
                                          : "the training stiffness on every candidate";
  }

  // Which point the rule chose (and whether the rule was met), and what was returned.
  std::string ReturnedFrom() const {
    const PathPoint* point = &path_.points[static_cast<std::size_t>(selected_)];
    std::string rule;
    if (options_.max_springs > 0) {
      rule =
          point && point->springs <= options_.max_springs
              ? fmt::format("the lowest E with at most {} springs", options_.max_springs)
              : fmt::format("no point has at most {} springs: the smallest", options_.max_springs);
    } else if (target_ > 0.0) {
      rule = point && point->normalized_error <= target_
                 ? fmt::format("the fewest springs with E <= {:.3g}", options_.target_error)
                 : fmt::format("no point reaches E {:.3g}: the lowest E", options_.target_error);
    } else {
      rule = "the fewest springs within 5% of the lowest E";
    }
    if (returned_ == selected_)
      return fmt::format("path point {} of {} ({}){}", returned_ + 1, path_.points.size(), rule,
                         refitted_ ? ", refitted" : "");
    if (returned_ >= 0)
      return fmt::format(
          "path point {} of {}, next in line: the final evaluation refused point {} ({}, {} "
          "springs)",
          returned_ + 1, path_.points.size(), selected_ + 1, rule, point->springs);
    if (options_.max_springs > 0 && PresentSprings(*start_) <= options_.max_springs)
      return fmt::format(
          "the start: no point of the path with at most {} springs passed the final evaluation",
          options_.max_springs);
    return "the start: no point of the path passed the final evaluation";
  }

  // Judged on the probe bank as a probe fit is, where the reference can be probed (a target
  // error: FitsToProbes), with the probe fit's baseline guarantee on the choosing probes. A
  // stop here leaves the model uncertified.
  void CertifyOnProbeBank() {
    if (stopped_ || path_.points.empty()) return;
    std::optional<ProbeCertificate> c;
    try {
      c = CertifyOnProbes(problem_, options_, weights_, *start_, &monitor_.interruption(), pool_);
    } catch (const Interrupted&) {
      r_.stop_message += "; stopped before the certificate: not judged on probes";
      MarkStopped();
      return;
    }
    if (!c) return;
    if (c->judgement_stopped) {
      r_.stop_message += "; stopped during the nonlinear judgement (not judged at amplitudes)";
      MarkStopped();
    }
    const response::Generalization& g = c->generalization;
    if (c->returned_baseline) {
      r_.stop_message += fmt::format(
          "; the closed-form baseline ({} springs) is returned: the fitted model's choosing "
          "error {:.3g} (over {} choosing probes) was not below the baseline's {:.3g}",
          PresentSprings(c->weights), g.fitted_choosing_error, g.choosing,
          g.baseline_choosing_error);
      ReturnBaseline(c->weights);
    }
    r_.stop_message += fmt::format(
        "; {}judged on {} held-out probes: median E {:.3g} (baseline {:.3g})",
        c->returned_baseline ? ""
                             : "fitted to the named cases (a target error chooses along their "
                               "path), ",
        g.held_out, g.model_held_out.median, g.baseline_held_out.median);
    r_.generalization = std::move(c->generalization);
  }

  // A stop during the certificate: the run ends stopped, not completed.
  void MarkStopped() {
    r_.stop = monitor_.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled;
  }

  // The closed-form baseline in place of the fitted model (the baseline guarantee).
  void ReturnBaseline(const std::vector<double>& baseline) {
    weights_ = baseline;
    Take(weights_);
    r_.evaluation = cost_.Evaluate(problem_.SpringsOfWeights(weights_));
    details_.chosen = -1;
    details_.held_out_normalized_error.reset();
    details_.held_out_per_case.clear();
    if (r_.stop == StopReason::kTargetReached && !(r_.evaluation.normalized_error <= target_))
      r_.stop = StopReason::kCompleted;
  }

  static CostOptions FinalCostOptions() {
    CostOptions o;
    o.solve_cases_of_mechanisms = true;
    return o;
  }

  const Problem& problem_;
  const SearchOptions& options_;
  const RunContext& context_;
  RunMonitor& monitor_;
  const int genes_;
  const double target_;  // the target error squared (0: none)
  const std::chrono::steady_clock::time_point start_time_;
  std::unique_ptr<WorkerPool> own_pool_;
  WorkerPool* pool_;
  const FitContext quiet_;
  const std::vector<bool> usable_;
  SparsityPathOptions path_options_;
  CostFunction cost_{problem_, FinalCostOptions()};

  IdentificationResult r_;
  IdentificationResult::Continuous details_;
  std::optional<std::vector<double>> start_;
  SparsityPath path_;
  std::vector<double> weights_;  // the model to return
  bool stopped_choosing_ = false;
  bool stopped_ = false;
  bool cancelled_ = false;
  // Where the returned model comes from: a path point (refitted, or as the path left it), or
  // the start (-1); `selected_` the rule's choice, before the final evaluation's fallbacks.
  int returned_ = -1;
  int selected_ = -1;
  bool refitted_ = false;
  // Progress.
  double current_error_ = std::numeric_limits<double>::quiet_NaN();
  int fit_steps_ = 0;
  int next_row_ = 1;
  int reported_steps_ = 0;
  std::size_t path_points_ = 0;
  double path_error_ = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace

IdentificationResult RunNamedCaseFit(const Problem& problem, const SearchOptions& options,
                                     const RunContext& context, RunMonitor& monitor) {
  return NamedCaseFit(problem, options, context, monitor).Run();
}

}  // namespace springfit
