#include "engine/identification/strategy.h"

#include <chrono>
#include <functional>
#include <map>
#include <memory>

namespace springfit {
namespace {

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Before the GA's first generation (not on a resumed run): a hook that may seed it.
using BeforeStart = std::function<void(GeneticSearch&, FitnessEvaluator&, IdentificationResult&)>;

IdentificationResult RunGenetic(const Problem& problem, const SearchOptions& options,
                                const RunContext& context, const BeforeStart& before_start) {
  std::unique_ptr<WorkerPool> own_pool;
  WorkerPool* pool = context.pool;
  if (!pool && context.threads > 1) {
    own_pool = std::make_unique<WorkerPool>(context.threads);
    pool = own_pool.get();
  }
  FitnessEvaluator evaluator(problem, pool, options.cache_capacity, context.use_cache);
  GeneticSearch search(problem, options, evaluator);  // the run's clock starts here

  IdentificationResult result;
  result.options = options;
  result.trace = context.trace;
  bool cancelled = false;
  auto last_report = std::chrono::steady_clock::now();
  search.SetInterruptPoll([&] {
    if (!context.on_beat || SecondsSince(last_report) < context.beat_seconds) return false;
    last_report = std::chrono::steady_clock::now();
    ProgressBeat beat;
    beat.wall_seconds = search.ElapsedSeconds();
    beat.generation = search.state().generation;
    beat.evaluations = evaluator.counters().evaluations;
    beat.best_normalized_error = search.state().best_fitness.normalized_error;
    return !context.on_beat(beat);
  });
  auto record = [&](const TraceRow& row) {
    result.trace.push_back(row);
    last_report = std::chrono::steady_clock::now();
    if (search.Interrupted()) cancelled = true;
    if (!context.on_iteration) return;
    IterationState state;
    state.finished = search.Finished() || cancelled;
    state.best = &search.state().best;
    if (!search.Interrupted()) state.snapshot = [&search] { return search.Snapshot(); };
    if (!context.on_iteration(row, state) && !search.Finished()) cancelled = true;
  };
  if (context.resume_from) {
    search.Restore(*context.resume_from);
  } else {
    if (before_start) before_start(search, evaluator, result);
    record(search.Initialize());
  }
  while (!cancelled && !search.Finished()) record(search.Step());

  const SearchState& state = search.state();
  result.stop = search.TargetReached()                        ? StopReason::kTargetReached
                : cancelled                                   ? StopReason::kCancelled
                : state.generation >= options.max_generations ? StopReason::kGenerationLimit
                : search.Stalled()                            ? StopReason::kStalled
                : search.TimeLimitReached()                   ? StopReason::kTimeLimit
                                                              : StopReason::kGenerationLimit;
  result.best = state.best;
  result.evaluation = evaluator.EvaluateInDetail(state.best);
  result.generations = state.generation;
  result.best_generation = state.best_generation;
  result.counters = evaluator.counters();
  result.wall_seconds = search.ElapsedSeconds();
  return result;
}

}  // namespace

IdentificationResult GeneticStrategy::Run(const Problem& problem, const SearchOptions& options,
                                          const RunContext& context) const {
  return RunGenetic(problem, options, context, nullptr);
}

IdentificationResult HybridStrategy::Run(const Problem& problem, const SearchOptions& options,
                                         const RunContext& context) const {
  return RunGenetic(
      problem, options, context,
      [&](GeneticSearch& search, FitnessEvaluator& evaluator, IdentificationResult& result) {
        // The GA's models have the training stiffness: the direct phase identifies topology only.
        const auto start = std::chrono::steady_clock::now();
        DirectOptions direct_options;
        direct_options.known_stiffness = problem.training_stiffness();
        const DirectResult direct = IdentifyDirect(problem, direct_options);
        IdentificationResult::DirectPhase phase;
        phase.seconds = SecondsSince(start);
        phase.normalized_error = evaluator.EvaluateInDetail(direct.genome).normalized_error;
        phase.difference = problem.CompareWithReference(direct.genome);
        result.direct_phase = phase;
        search.SeedInitialPopulation({direct.genome}, phase.seconds);  // its time starts the clock
      });
}

IdentificationResult DirectStrategy::Run(const Problem& problem, const SearchOptions& options,
                                         const RunContext& context) const {
  IdentificationResult r;
  r.options = options;
  const auto start = std::chrono::steady_clock::now();
  DirectOptions direct_options;
  if (options.identify == Identify::kTopology)
    direct_options.known_stiffness = problem.training_stiffness();
  DirectResult direct = IdentifyDirect(problem, direct_options);
  r.best = direct.genome;
  r.evaluation = direct.evaluation;
  r.counters.evaluations = direct.evaluations;
  r.wall_seconds = SecondsSince(start);
  const double target = std::max(options.target_normalized_error, kExactNormalizedError);
  r.stop =
      r.evaluation.normalized_error <= target ? StopReason::kTargetReached : StopReason::kCompleted;
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
    // One solve: a cancel asked during it takes effect when it returns.
    if (!context.on_iteration(row, state) && r.stop != StopReason::kTargetReached)
      r.stop = StopReason::kCancelled;
  }
  return r;
}

std::unique_ptr<IdentificationStrategy> MakeStrategy(Strategy strategy) {
  switch (strategy) {
    case Strategy::kPaper:
      return std::make_unique<GeneticStrategy>();
    case Strategy::kDirect:
      return std::make_unique<DirectStrategy>();
    case Strategy::kHybrid:
    case Strategy::kDefault:
      return std::make_unique<HybridStrategy>();
  }
  return std::make_unique<GeneticStrategy>();
}

}  // namespace springfit
