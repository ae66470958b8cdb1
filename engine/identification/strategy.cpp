#include "engine/identification/strategy.h"

#include <chrono>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string_view>

#include "engine/fit/sparsity_path.h"

namespace springfit {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// A model a phase before the GA found and evaluated in detail: the result when the run is
// stopped before the GA's first population is evaluated.
struct Seed {
  Genome genome;
  Evaluation evaluation;
};

// Before the GA's first generation (not on a resumed run): a hook that may seed it.
using BeforeStart =
    std::function<std::optional<Seed>(GeneticSearch&, FitnessEvaluator&, IdentificationResult&)>;

IdentificationResult RunGenetic(const Problem& problem, const SearchOptions& options,
                                const RunContext& context, RunMonitor& monitor,
                                const BeforeStart& before_start) {
  std::unique_ptr<WorkerPool> own_pool;
  WorkerPool* pool = PoolOf(context, own_pool);
  FitnessEvaluator evaluator(problem, pool, options.cache_capacity, context.use_cache);
  evaluator.set_interruption(&monitor.interruption());
  GeneticSearch search(problem, options, evaluator);  // the run's clock starts here
  search.set_interruption(&monitor.interruption());

  IdentificationResult result;
  result.options = options;
  result.trace = context.trace;
  bool cancelled = false;
  const auto genetic_phase = [&] {
    monitor.SetPhase("genetic", [&](ProgressBeat& beat) {
      const SearchState& state = search.state();
      beat.wall_seconds = search.ElapsedSeconds();
      beat.generation = state.generation;
      beat.evaluations = evaluator.counters().evaluations;
      beat.best_normalized_error = state.best.empty() ? std::numeric_limits<double>::quiet_NaN()
                                                      : state.best_fitness.normalized_error;
    });
  };
  auto record = [&](const TraceRow& row) {
    result.trace.push_back(row);
    monitor.Reported();
    // (Short generations postpone every poll: the time limit is also checked here.)
    if (search.Interrupted() || monitor.TimeLimitPassed()) cancelled = true;
    if (!context.on_iteration) return;
    IterationState state;
    state.finished = search.Finished() || cancelled;
    state.best = &search.state().best;
    if (!search.Interrupted()) state.snapshot = [&search] { return search.Snapshot(); };
    if (!context.on_iteration(row, state) && !search.Finished()) cancelled = true;
  };
  std::optional<Seed> seed;
  try {
    genetic_phase();
    if (context.resume_from) {
      search.Restore(*context.resume_from);
    } else {
      if (before_start) seed = before_start(search, evaluator, result);
      genetic_phase();
      record(search.Initialize());
    }
    while (!cancelled && !search.Finished()) record(search.Step());
  } catch (const Interrupted&) {
    cancelled = true;  // mid-step: the best so far stands
  }
  evaluator.set_interruption(nullptr);  // the best's evaluation below runs to its end

  const SearchState& state = search.state();
  const StopReason stopped =
      monitor.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled;
  result.counters = evaluator.counters();
  result.wall_seconds = search.ElapsedSeconds();
  if (state.best.empty()) {
    // Stopped while the first population was being evaluated.
    if (!seed) throw Interrupted();
    result.stop = stopped;
    result.best = seed->genome;
    result.evaluation = std::move(seed->evaluation);
    return result;
  }
  result.stop = search.TargetReached()                        ? StopReason::kTargetReached
                : cancelled                                   ? stopped
                : state.generation >= options.max_generations ? StopReason::kGenerationLimit
                : search.Stalled()                            ? StopReason::kStalled
                : search.TimeLimitReached()                   ? StopReason::kTimeLimit
                                                              : StopReason::kGenerationLimit;
  result.best = state.best;
  result.evaluation = evaluator.EvaluateInDetail(state.best);
  result.generations = state.generation;
  result.best_generation = state.best_generation;
  return result;
}

// Beats of a phase that has only its own clock to report.
void ClockPhase(RunMonitor& monitor, std::string_view phase,
                std::chrono::steady_clock::time_point start) {
  monitor.SetPhase(phase, [start](ProgressBeat& beat) {
    beat.wall_seconds = SecondsSince(start);
    beat.best_normalized_error = std::numeric_limits<double>::quiet_NaN();
  });
}

}  // namespace

IdentificationResult GeneticStrategy::Run(const Problem& problem, const SearchOptions& options,
                                          const RunContext& context, RunMonitor& monitor) const {
  return RunGenetic(problem, options, context, monitor, nullptr);
}

IdentificationResult HybridStrategy::Run(const Problem& problem, const SearchOptions& options,
                                         const RunContext& context, RunMonitor& monitor) const {
  return RunGenetic(
      problem, options, context, monitor,
      [&](GeneticSearch& search, FitnessEvaluator& evaluator, IdentificationResult& result) {
        // The GA's models have the training stiffness: the direct phase identifies topology only.
        const auto start = std::chrono::steady_clock::now();
        ClockPhase(monitor, "direct", start);
        DirectOptions direct_options;
        direct_options.known_stiffness = problem.training_stiffness();
        const DirectResult direct =
            IdentifyDirect(problem, direct_options, &monitor.interruption());
        Seed seed{direct.genome, evaluator.EvaluateInDetail(direct.genome)};
        if (seed.evaluation.interrupted) throw Interrupted();
        IdentificationResult::DirectPhase phase;
        phase.seconds = SecondsSince(start);
        phase.normalized_error = seed.evaluation.normalized_error;
        phase.difference = problem.CompareWithReference(direct.genome);
        result.direct_phase = phase;
        search.SeedInitialPopulation({direct.genome}, phase.seconds);  // its time starts the clock
        return seed;
      });
}

IdentificationResult DirectStrategy::Run(const Problem& problem, const SearchOptions& options,
                                         const RunContext& context, RunMonitor& monitor) const {
  IdentificationResult r;
  r.options = options;
  const auto start = std::chrono::steady_clock::now();
  ClockPhase(monitor, "direct", start);
  DirectOptions direct_options;
  if (options.identify == Identify::kTopology)
    direct_options.known_stiffness = problem.training_stiffness();
  DirectResult direct = IdentifyDirect(problem, direct_options, &monitor.interruption());
  r.best = direct.genome;
  r.evaluation = direct.evaluation;
  r.counters.evaluations = direct.evaluations;
  r.wall_seconds = SecondsSince(start);
  const double target = std::max(options.target_normalized_error, kExactNormalizedError);
  r.stop = r.evaluation.normalized_error <= target ? StopReason::kTargetReached
                                                   : StopReason::kNotReproduced;
  // Per spring of the genome (candidate order), the identified stiffness.
  std::map<int, double> stiffness_of;
  for (int m = 0; m < direct.springs.size(); ++m)
    stiffness_of[direct.springs.index[m]] = direct.springs.stiffness[m];
  for (std::size_t g = 0; g < r.best.size(); ++g) {
    if (!r.best[g]) continue;
    const auto it = stiffness_of.find(problem.gene_candidates()[g]);
    r.stiffness.push_back(it != stiffness_of.end() ? it->second : problem.training_stiffness());
  }

  TraceRow row;
  row.wall_seconds = r.wall_seconds;
  row.evaluations = r.counters.evaluations;
  row.best_cost = r.evaluation.cost;
  row.best_normalized_error = r.evaluation.normalized_error;
  row.mean_cost = r.evaluation.cost;
  if (const auto difference = problem.CompareWithReference(r.best)) {
    row.missing = static_cast<int>(difference->missing.size());
    row.extra = static_cast<int>(difference->extra.size());
  }
  r.trace.push_back(row);
  r.direct = std::move(direct);
  if (context.on_iteration) {
    IterationState state;
    state.finished = true;
    state.best = &r.best;
    if (!context.on_iteration(row, state) && r.stop != StopReason::kTargetReached)
      r.stop = StopReason::kCancelled;
  }
  return r;
}

IdentificationResult ContinuousStrategy::Run(const Problem& problem, const SearchOptions& options,
                                             const RunContext& context, RunMonitor& monitor) const {
  if (FitsToProbes(problem, options)) return RunProbeFit(problem, options, context, monitor);
  IdentificationResult r;
  r.options = options;  // (RunIdentification sets identify: continuous identifies stiffness)
  r.trace = context.trace;
  const auto start_time = std::chrono::steady_clock::now();
  const int genes = problem.gene_count();
  SparsityPathOptions path_options;

  // The start: the closed-form baseline where it is a model of the candidates.
  IdentificationResult::Continuous details;
  std::optional<std::vector<double>> start;
  if (problem.scene().reference.kind == Reference::Kind::kFem)
    start = fem::BaselineGeneWeights(problem);
  details.started_from_baseline = start.has_value();
  if (!start)
    start = std::vector<double>(static_cast<std::size_t>(genes), problem.training_stiffness());

  std::unique_ptr<WorkerPool> own_pool;
  WorkerPool* pool = PoolOf(context, own_pool);
  const FitContext quiet{&monitor.interruption(), pool, {}};
  std::vector<bool> usable(static_cast<std::size_t>(genes), true);
  // The regularisation: the setting's, or the one whose held-out error is lowest.
  path_options.fit.regularization = options.regularization;
  bool stopped_choosing = false;
  if (options.choose_regularization) {
    ClockPhase(monitor, "regularization", std::chrono::steady_clock::now());
    try {
      if (const auto choice = ChooseRegularization(problem, *start, usable, path_options, quiet)) {
        path_options.fit.regularization = choice->chosen;
        details.regularization_strengths = choice->strengths;
        details.regularization_held_out = choice->held_out_normalized_errors;
      }
    } catch (const Interrupted&) {
      stopped_choosing = true;  // before any fit: the start is returned
    }
  }
  details.regularization = path_options.fit.regularization;

  // Progress: beats carry the error of the last accepted step; trace rows follow the first fit.
  double current_error = std::numeric_limits<double>::quiet_NaN();
  int fit_steps = 0;
  bool cancelled = false;
  monitor.SetPhase("fit", [&](ProgressBeat& beat) {
    beat.wall_seconds = SecondsSince(start_time);
    beat.generation = static_cast<int>(r.trace.size());
    beat.evaluations = fit_steps;
    beat.best_normalized_error = current_error;
  });
  const auto report = [&](const std::vector<double>& weights, double normalized_error, int steps) {
    TraceRow row;
    row.generation = static_cast<int>(r.trace.size());
    row.wall_seconds = SecondsSince(start_time);
    row.evaluations = steps;
    row.best_normalized_error = normalized_error;
    row.best_cost = normalized_error * problem.reference_norm2();
    row.mean_cost = row.best_cost;
    r.trace.push_back(row);
    monitor.Reported();
    if (monitor.TimeLimitPassed()) cancelled = true;
    if (!context.on_iteration) return;
    Genome best(static_cast<std::size_t>(genes), 0);
    for (int g = 0; g < genes; ++g) best[g] = weights[g] > 0.0;
    IterationState state;
    state.best = &best;
    if (!context.on_iteration(row, state)) cancelled = true;
  };
  int next_row = 1;
  int reported_steps = 0;
  const FitStepCallback on_step = [&](const std::vector<double>& w, double e, int accepted) {
    current_error = e;
    fit_steps = accepted;
    if (accepted == next_row) {
      next_row *= 2;
      reported_steps = accepted;
      report(w, e, accepted);
      if (cancelled) throw Interrupted();  // the fit returns its last accepted step
    }
  };
  std::size_t path_points = 0;
  double path_error = std::numeric_limits<double>::quiet_NaN();
  const PathProgress on_point = [&](const SparsityPath& path) {
    if (path.points.size() == 1) {
      if (reported_steps != path.fit.accepted) {
        reported_steps = path.fit.accepted;
        report(path.fit.weights, path.fit.normalized_error, path.fit.accepted);  // the fit's end
      }
      // Beats now describe the path: its points so far and the last one's error.
      monitor.SetPhase("path", [&](ProgressBeat& beat) {
        beat.wall_seconds = SecondsSince(start_time);
        beat.generation = static_cast<int>(path_points);
        beat.evaluations = fit_steps;
        beat.best_normalized_error = path_error;
      });
    }
    path_points = path.points.size();
    path_error = path.points.back().normalized_error;
    if (cancelled) throw Interrupted();  // the path so far stands
  };

  const FitContext fit_context{&monitor.interruption(), pool, on_step};

  // Sizes and errors: a size limit traces the path at least that far.
  const double target = options.target_error * options.target_error;
  const double stop = options.max_springs > 0 ? std::numeric_limits<double>::infinity() : target;
  SparsityPath path;
  if (!stopped_choosing) {
    path = TraceSparsityPath(problem, *start, usable, path_options, stop, options.max_springs,
                             fit_context, on_point);
  }
  if (path.points.empty() && details.started_from_baseline && !stopped_choosing) {
    // The baseline has no equilibrium (a nonlinear response at a large load): the training
    // stiffness on every candidate instead.
    details.started_from_baseline = false;
    start = std::vector<double>(static_cast<std::size_t>(genes), problem.training_stiffness());
    path = TraceSparsityPath(problem, *start, usable, path_options, stop, options.max_springs,
                             fit_context, on_point);
  }
  details.steps = path.steps;
  details.solves = path.solves;
  bool stopped = path.interrupted || cancelled || stopped_choosing;
  std::vector<double> weights = *start;
  // Where the returned model comes from: a path point (refitted, or as the path left it), or
  // the start (index -1).
  bool refitted = false;
  int returned = -1;
  int selected = -1;  // the rule's choice, before the final evaluation's fallbacks
  if (!path.points.empty()) {
    for (const PathPoint& point : path.points)
      details.path.push_back({point.springs, point.normalized_error});
    details.fit_normalized_error = path.fit.normalized_error;
    details.start_normalized_error = path.fit.initial_normalized_error;
    returned = selected = static_cast<int>(
        SelectPathPoint(path, options.max_springs, target, path_options.tolerance));
    weights = path.points[static_cast<std::size_t>(returned)].weights;
    try {
      if (!stopped) {
        // The chosen point, refitted on its own springs (no pruning follows: no saliency).
        ClockPhase(monitor, "refit", std::chrono::steady_clock::now());
        std::vector<bool> support(weights.size());
        for (std::size_t g = 0; g < weights.size(); ++g) support[g] = weights[g] > 0.0;
        StiffnessFitOptions refit_options = path_options.fit;
        refit_options.upper_bound = path.upper_bound;
        refit_options.saliency_probes = 0;
        const StiffnessFitResult refit =
            FitStiffness(problem, weights, FitScope{support, {}, *start}, refit_options, quiet);
        details.steps += refit.iterations;
        details.solves += refit.solves;
        if (refit.feasible) {
          weights = refit.weights;
          refitted = true;
        }
        stopped = refit.interrupted;
      }
    } catch (const Interrupted&) {
      stopped = true;
    }
  }

  // The returned model is judged by the evaluation every strategy's is (each case solved
  // from the reference's equilibrium, cost.h). The fit's solves start from the last step's
  // equilibria, and a nonlinear model near a mechanism can have an equilibrium there that
  // Newton from the reference does not reach: a model without equilibrium in that evaluation,
  // or worse than the start, is not returned. The next in line are the chosen point as the path
  // left it, the other points by error, and the start (the baseline).
  CostOptions cost_options;
  cost_options.solve_cases_of_mechanisms = true;
  CostFunction cost(problem, cost_options);
  std::vector<int> next_in_line;  // path points and the start (-1), in the order tried
  if (!path.points.empty()) {
    for (int i = 0; i < static_cast<int>(path.points.size()); ++i) next_in_line.push_back(i);
    std::stable_sort(next_in_line.begin(), next_in_line.end(), [&](int a, int b) {
      return path.points[a].normalized_error < path.points[b].normalized_error;
    });
    // A size limit is kept as long as some model meets it: those that do first (the start
    // among them when it does: the baseline on the mesh edges can be smaller than any path
    // point better than it).
    const int limit = options.max_springs;
    const auto within = [&](int i) {
      return limit > 0 && (i >= 0 ? path.points[static_cast<std::size_t>(i)].springs
                                  : PresentSprings(*start)) <= limit;
    };
    auto end_within = std::stable_partition(next_in_line.begin(), next_in_line.end(), within);
    next_in_line.insert(within(-1) ? end_within : next_in_line.end(), -1);
    std::stable_partition(next_in_line.begin(), next_in_line.end(),
                          [&](int i) { return i == returned; });
    if (!refitted) next_in_line.erase(next_in_line.begin());  // (the point itself failed)
  } else {
    next_in_line.push_back(-1);
  }
  const auto acceptable = [&](const Evaluation& e) {
    return e.converged && !e.mechanism &&
           (path.points.empty() ||
            e.normalized_error <= details.start_normalized_error * (1.0 + 1e-9));
  };
  r.evaluation = cost.Evaluate(problem.SpringsOfWeights(weights));
  for (std::size_t i = 0; i < next_in_line.size() && !acceptable(r.evaluation); ++i) {
    ++details.rejected;
    returned = next_in_line[i];
    refitted = false;
    weights = returned >= 0 ? path.points[static_cast<std::size_t>(returned)].weights : *start;
    r.evaluation = cost.Evaluate(problem.SpringsOfWeights(weights));
  }
  details.chosen = returned;
  details.model_seconds = SecondsSince(start_time);
  // The returned model's generalisation: each load case predicted by its springs fitted to
  // the others.
  if (!stopped && !path.points.empty()) {
    ClockPhase(monitor, "held_out", std::chrono::steady_clock::now());
    try {
      if (const auto held_out = HeldOutErrors(problem, weights, *start, path_options, quiet)) {
        details.held_out_normalized_error = held_out->normalized_error;
        details.held_out_per_case = held_out->per_case;
      }
    } catch (const Interrupted&) {
      stopped = true;
    }
  }

  const auto take = [&](const std::vector<double>& model) {
    r.best.assign(static_cast<std::size_t>(genes), 0);
    r.stiffness.clear();
    for (int g = 0; g < genes; ++g) {
      if (model[g] > 0.0) {
        r.best[g] = 1;
        r.stiffness.push_back(model[g]);  // gene order is candidate order
      }
    }
  };
  take(weights);
  r.counters.evaluations = details.steps;
  r.wall_seconds = SecondsSince(start_time);
  const double e = r.evaluation.normalized_error;
  r.stop = stopped
               ? (monitor.time_limit_reached() ? StopReason::kTimeLimit : StopReason::kCancelled)
           : target > 0.0 && e <= target ? StopReason::kTargetReached
                                         : StopReason::kCompleted;
  char message[512];
  if (stopped_choosing) {
    std::snprintf(message, sizeof message,
                  "%s while the regularisation was chosen, before any fit: the start (%s) at E "
                  "%.3g",
                  r.stop == StopReason::kTimeLimit ? "time limit reached" : "stopped on request",
                  details.started_from_baseline ? "the closed-form baseline"
                                                : "the training stiffness on every candidate",
                  std::sqrt(e));
  } else if (path.points.empty()) {
    std::snprintf(message, sizeof message,
                  "no model with an equilibrium in every load case to start from (the start is a "
                  "mechanism or does not converge)%s",
                  problem.response() == Response::kNonlinear
                      ? ": try the linear response (search.response) or smaller loads"
                      : ": try more candidates");
  } else {
    // Which point, by which rule (and whether the rule was met), and what was returned.
    char rule[160];
    const PathPoint* point = &path.points[static_cast<std::size_t>(selected)];
    if (options.max_springs > 0) {
      std::snprintf(rule, sizeof rule,
                    point && point->springs <= options.max_springs
                        ? "the lowest E with at most %d springs"
                        : "no point has at most %d springs: the smallest",
                    options.max_springs);
    } else if (target > 0.0) {
      std::snprintf(rule, sizeof rule,
                    point && point->normalized_error <= target
                        ? "the fewest springs with E <= %.3g"
                        : "no point reaches E %.3g: the lowest E",
                    options.target_error);
    } else {
      std::snprintf(rule, sizeof rule, "the fewest springs within 5%% of the lowest E");
    }
    char from[320];
    if (returned == selected) {
      std::snprintf(from, sizeof from, "path point %d of %zu (%s)%s", returned + 1,
                    path.points.size(), rule, refitted ? ", refitted" : "");
    } else if (returned >= 0) {
      std::snprintf(from, sizeof from,
                    "path point %d of %zu, next in line: the final evaluation refused point %d "
                    "(%s, %d springs)",
                    returned + 1, path.points.size(), selected + 1, rule, point->springs);
    } else {
      if (options.max_springs > 0 && PresentSprings(*start) <= options.max_springs) {
        std::snprintf(from, sizeof from,
                      "the start: no point of the path with at most %d springs passed the final "
                      "evaluation",
                      options.max_springs);
      } else {
        std::snprintf(from, sizeof from,
                      "the start: no point of the path passed the final evaluation");
      }
    }
    char refused[160] = "";
    if (details.rejected > 0)
      std::snprintf(refused, sizeof refused,
                    "; %d model(s) refused by the final evaluation (no equilibrium from the "
                    "reference's, or worse than the start)",
                    details.rejected);
    std::snprintf(
        message, sizeof message,
        "%s%d springs at E %.3g, from %s; the fit on every candidate reached E %.3g from %.3g "
        "at its start (%s)%s",
        stopped ? (r.stop == StopReason::kTimeLimit ? "time limit reached; the best so far: "
                                                    : "stopped on request; the best so far: ")
                : "",
        PresentSprings(weights), std::sqrt(e), from, std::sqrt(details.fit_normalized_error),
        std::sqrt(details.start_normalized_error),
        details.started_from_baseline ? "the closed-form baseline"
                                      : "the training stiffness on every candidate",
        refused);
  }
  r.stop_message = message;
  // Judged on the probe bank as a probe fit is, where the reference can be probed (a target
  // error: FitsToProbes).
  if (!stopped && !path.points.empty()) {
    r.generalization = CertifyOnProbes(problem, options, weights, *start);
    if (r.generalization) {
      char judged[200];
      std::snprintf(judged, sizeof judged,
                    "; fitted to the named cases (a target error chooses along their path), "
                    "judged on %d held-out probes: median E %.3g (baseline %.3g)",
                    r.generalization->held_out, r.generalization->model_held_out.median,
                    r.generalization->baseline_held_out.median);
      r.stop_message += judged;
      // The baseline guarantee on unseen loads (issue 31 item 4), as the probe fit keeps it: a
      // model no better than the closed-form baseline on the held-out probes (one that leaves
      // a mode free is infinitely worse) gives way to the baseline, within the spring budget.
      const response::Generalization& g = *r.generalization;
      const bool within_budget =
          options.max_springs == 0 || PresentSprings(*start) <= options.max_springs;
      if (details.started_from_baseline && within_budget &&
          !(g.model_held_out.rms < g.baseline_held_out.rms)) {
        std::snprintf(judged, sizeof judged,
                      "; the closed-form baseline (%d springs) is returned: the fitted model's "
                      "held-out E (RMS over %d probes) %.3g was not below the baseline's %.3g",
                      PresentSprings(*start), g.held_out, g.model_held_out.rms,
                      g.baseline_held_out.rms);
        r.stop_message += judged;
        weights = *start;
        take(weights);
        r.evaluation = cost.Evaluate(problem.SpringsOfWeights(weights));
        details.chosen = -1;
        details.held_out_normalized_error.reset();
        details.held_out_per_case.clear();
        r.generalization = CertifyOnProbes(problem, options, weights, *start);
        r.generalization->returned_baseline = true;
        if (r.stop == StopReason::kTargetReached && !(r.evaluation.normalized_error <= target))
          r.stop = StopReason::kCompleted;
      }
    }
  }
  r.continuous = std::move(details);
  return r;
}

WorkerPool* PoolOf(const RunContext& context, std::unique_ptr<WorkerPool>& own) {
  if (context.pool || context.threads <= 1) return context.pool;
  own = std::make_unique<WorkerPool>(context.threads);
  return own.get();
}

Strategy ResolvedStrategy(Strategy strategy, const Problem& problem) {
  return ResolvedStrategy(strategy, problem.scene());
}

std::unique_ptr<IdentificationStrategy> MakeStrategy(Strategy strategy, const Problem& problem) {
  switch (ResolvedStrategy(strategy, problem)) {
    case Strategy::kPaper:
      return std::make_unique<GeneticStrategy>();
    case Strategy::kDirect:
      return std::make_unique<DirectStrategy>();
    case Strategy::kHybrid:
      return std::make_unique<HybridStrategy>();
    case Strategy::kContinuous:
      return std::make_unique<ContinuousStrategy>();
    case Strategy::kDefault:  // (resolved above)
      break;
  }
  return std::make_unique<GeneticStrategy>();
}

}  // namespace springfit
