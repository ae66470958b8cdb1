// The records every identification strategy shares, below all of them: one row of the trace
// per iteration, and why a run stopped.
#pragma once

#include <cstdint>
#include <string_view>

namespace springfit {

// One row of the trace per iteration: for the genetic strategies generation 0 is the initial
// population and each later row one generation; strategy direct has one row (generation 0).
struct TraceRow {
  int generation = 0;
  double wall_seconds = 0.0;     // since the run started (not reproducible)
  std::int64_t evaluations = 0;  // genomes evaluated so far, cache hits included
  std::int64_t cache_hits = 0;   // so far
  double best_cost = 0.0;        // of the best model found so far
  double best_normalized_error = 0.0;
  double mean_cost = 0.0;  // over the current population (penalties included)
  int missing = -1;        // best model against the reference topology; -1 = unknown
  int extra = -1;

  // Equal in everything but wall time.
  bool SameSearch(const TraceRow& o) const {
    return generation == o.generation && evaluations == o.evaluations &&
           cache_hits == o.cache_hits && best_cost == o.best_cost &&
           best_normalized_error == o.best_normalized_error && mean_cost == o.mean_cost &&
           missing == o.missing && extra == o.extra;
  }
  // The same but for cache hits: a run resumed from a checkpoint starts with an empty fitness
  // cache, which changes how many evaluations it answers from the cache and nothing else.
  bool SameSearchButCacheHits(const TraceRow& o) const {
    TraceRow same_hits = *this;
    same_hits.cache_hits = o.cache_hits;
    return same_hits.SameSearch(o);
  }
};

// Why an identification stopped; each value's criterion is exact.
enum class StopReason {
  kTargetReached,    // the best model's normalised error <= max(target, kExactNormalizedError)
  kGenerationLimit,  // max_generations generations were bred without reaching the target
  kCancelled,        // the run's callback returned false (cancel, shutdown, Ctrl-C)
  kCompleted,        // continuous ran to its end without (or short of) a target_error
  kTimeLimit,        // max_seconds of wall time had passed since the run began (inside a step)
  kStalled,          // the best did not improve for stall_generations generations
  // The run ended (none of the above by request or time) with a model that is no answer:
  kMechanism,      // the best model is a mechanism: it cannot carry some load case
  kNoEquilibrium,  // the best model's equilibrium was not found under some load case
  kNotReproduced,  // direct ran to its end and its model does not reproduce the reference
                   // (normalised error above the target)
};

}  // namespace springfit
