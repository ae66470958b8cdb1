#include "engine/identification/strategy.h"

#include <chrono>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string_view>

#include "engine/direct/direct_identification.h"
#include "engine/fit/sparsity_path.h"
#include "engine/search/genetic_search.h"

namespace springfit {
namespace {

// A model a phase before the GA found and evaluated in detail: the result when the run is
// stopped before the GA's first population is evaluated.
struct Seed {
  Genome genome;
  Evaluation evaluation;
};

// A phase before the GA's first generation that may seed it. `run` runs it on a fresh run;
// on a run resumed from a checkpoint, `resumed` reports it again from the checkpoint's seeds
// and seconds (SearchState::seeds), so that a resumed job's result says what an uninterrupted
// one says.
struct Preamble {
  std::function<std::optional<Seed>(GeneticSearch&, FitnessEvaluator&, IdentificationResult&)> run;
  std::function<void(const SearchState&, FitnessEvaluator&, IdentificationResult&)> resumed;
};

IdentificationResult RunGenetic(const Problem& problem, const SearchOptions& options,
                                const RunContext& context, RunMonitor& monitor,
                                const Preamble* preamble) {
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
      // (Before Restore, which sets the evaluator's counters to the checkpoint's.)
      if (preamble && !context.resume_from->seeds.empty())
        preamble->resumed(*context.resume_from, evaluator, result);
      search.Restore(*context.resume_from);
    } else {
      if (preamble) seed = preamble->run(search, evaluator, result);
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

}  // namespace

IdentificationResult GeneticStrategy::Run(const Problem& problem, const SearchOptions& options,
                                          const RunContext& context, RunMonitor& monitor) const {
  return RunGenetic(problem, options, context, monitor, nullptr);
}

IdentificationResult HybridStrategy::Run(const Problem& problem, const SearchOptions& options,
                                         const RunContext& context, RunMonitor& monitor) const {
  // The direct phase as the result reports it: its topology's error at the training stiffness.
  const auto report = [&](const Genome& topology, const Evaluation& evaluation, double seconds,
                          IdentificationResult& result) {
    if (evaluation.interrupted) throw Interrupted();
    IdentificationResult::DirectPhase phase;
    phase.seconds = seconds;
    phase.normalized_error = evaluation.normalized_error;
    phase.difference = problem.CompareWithReference(topology);
    result.direct_phase = phase;
  };
  Preamble direct_phase;
  direct_phase.run = [&](GeneticSearch& search, FitnessEvaluator& evaluator,
                         IdentificationResult& result) {
    // The GA's models have the training stiffness: the direct phase identifies topology only.
    const auto start = std::chrono::steady_clock::now();
    ClockPhase(monitor, "direct", start);
    DirectOptions direct_options;
    direct_options.known_stiffness = problem.training_stiffness();
    const DirectResult direct = IdentifyDirect(problem, direct_options, &monitor.interruption());
    Seed seed{direct.genome, evaluator.EvaluateInDetail(direct.genome)};
    const double seconds = SecondsSince(start);
    report(seed.genome, seed.evaluation, seconds, result);
    search.SeedInitialPopulation({direct.genome}, seconds);  // its time starts the clock
    return std::optional<Seed>(std::move(seed));
  };
  direct_phase.resumed = [&](const SearchState& state, FitnessEvaluator& evaluator,
                             IdentificationResult& result) {
    const Genome& topology = state.seeds.front();
    report(topology, evaluator.EvaluateInDetail(topology), state.seeded_seconds, result);
  };
  return RunGenetic(problem, options, context, monitor, &direct_phase);
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
  return RunNamedCaseFit(problem, options, context, monitor);
}

WorkerPool* PoolOf(const RunContext& context, std::unique_ptr<WorkerPool>& own) {
  if (context.pool || context.threads <= 1) return context.pool;
  own = std::make_unique<WorkerPool>(context.threads);
  return own.get();
}

std::unique_ptr<IdentificationStrategy> MakeStrategy(Strategy strategy, const Problem& problem) {
  switch (ResolvedStrategy(strategy, problem.scene())) {
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
