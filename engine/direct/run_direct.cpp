#include "engine/direct/run_direct.h"

#include <algorithm>
#include <chrono>

namespace springfit {

DirectRun RunDirect(const Problem& problem, const SearchOptions& options, const DirectOptions& direct_options) {
  DirectRun run;
  SearchResult& r = run.search;
  r.identifiability = AnalyseIdentifiability(problem);  // before the clock, as for the GAs
  r.baseline = fem::EvaluateClosedFormBaseline(problem);
  const auto start = std::chrono::steady_clock::now();
  DirectOptions resolved = direct_options;
  if (options.identify == Identify::kTopology) resolved.known_stiffness = problem.training_stiffness();
  run.direct = IdentifyDirect(problem, resolved);
  r.options = options;
  r.best = run.direct.genome;
  r.springs = problem.SpringsOfGenome(r.best);
  r.evaluation = run.direct.evaluation;
  r.difference = problem.CompareWithReference(r.best);
  r.counters.evaluations = run.direct.evaluations;
  r.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double target = std::max(options.target_normalized_error, kExactNormalizedError);
  r.stop = r.evaluation.normalized_error <= target ? StopReason::kTargetReached : StopReason::kCompleted;

  TraceRow row;
  row.wall_seconds = r.wall_seconds;
  row.evaluations = r.counters.evaluations;
  row.best_cost = r.evaluation.cost;
  row.best_normalized_error = r.evaluation.normalized_error;
  row.mean_cost = r.evaluation.cost;
  if (r.difference) {
    row.missing = static_cast<int>(r.difference->missing.size());
    row.extra = static_cast<int>(r.difference->extra.size());
  }
  r.trace.push_back(row);
  return run;
}

}  // namespace springfit
