#include "engine/search/run_search.h"

#include <chrono>
#include <memory>

#include "engine/direct/direct_identification.h"

namespace springfit {

SearchResult RunSearch(const Problem& problem, const SearchOptions& options, const RunOptions& run) {
  std::unique_ptr<WorkerPool> own_pool;
  WorkerPool* pool = run.pool;
  if (!pool && run.threads > 1) {
    own_pool = std::make_unique<WorkerPool>(run.threads);
    pool = own_pool.get();
  }
  // Before the search's clock starts (it starts with the GeneticSearch): not part of its time.
  SearchResult result;
  result.identifiability = AnalyseIdentifiability(problem);
  result.baseline = fem::EvaluateClosedFormBaseline(problem);
  FitnessEvaluator evaluator(problem, pool, options.cache_capacity, run.use_cache);
  GeneticSearch search(problem, options, evaluator);

  result.options = options;
  result.trace = run.trace;
  bool cancelled = false;
  auto record = [&](const TraceRow& row) {
    result.trace.push_back(row);
    if (run.on_generation && !run.on_generation(row, search) && !search.Finished()) cancelled = true;
  };
  if (run.resume_from) {
    search.Restore(*run.resume_from);
  } else {
    if (options.direct_seed) {
      // The direct identification seeds the GA; its time starts the trace's clock.
      const auto start = std::chrono::steady_clock::now();
      // The GA's models have the training stiffness: the direct phase identifies topology only.
      DirectOptions direct_options;
      direct_options.known_stiffness = problem.training_stiffness();
      const DirectResult direct = IdentifyDirect(problem, direct_options);
      SearchResult::DirectPhase phase;
      phase.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      phase.normalized_error = evaluator.EvaluateInDetail(direct.genome).normalized_error;
      phase.difference = problem.CompareWithReference(direct.genome);
      result.direct_phase = phase;
      search.SeedInitialPopulation({direct.genome}, phase.seconds);
    }
    record(search.Initialize());
  }
  while (!cancelled && !search.Finished()) record(search.Step());

  const SearchState& state = search.state();
  result.stop = search.TargetReached() ? StopReason::kTargetReached
                : cancelled            ? StopReason::kCancelled
                                       : StopReason::kGenerationLimit;
  result.best = state.best;
  result.springs = problem.SpringsOfGenome(state.best);
  result.evaluation = evaluator.EvaluateInDetail(state.best);
  result.difference = problem.CompareWithReference(state.best);
  result.generations = state.generation;
  result.best_generation = state.best_generation;
  result.counters = evaluator.counters();
  result.wall_seconds = search.ElapsedSeconds();
  return result;
}

}  // namespace springfit
