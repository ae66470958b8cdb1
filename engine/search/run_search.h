// Runs a topology search to its end: the target reached, the generation limit, or a stop
// asked by the progress callback. The engine's entry point for `springfit run`, the daemon
// and the experiment driver.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "engine/cost.h"
#include "engine/direct/identifiability.h"
#include "engine/fem/closed_form_baseline.h"
#include "engine/problem.h"
#include "engine/search/genetic_search.h"
#include "engine/search/search_options.h"
#include "engine/search/worker_pool.h"

namespace springfit {

// kCompleted: a single-shot strategy (direct) ran to its end without reaching the target.
enum class StopReason { kTargetReached, kGenerationLimit, kCancelled, kCompleted };

struct SearchResult {
  SearchOptions options;
  StopReason stop = StopReason::kGenerationLimit;
  Genome best;
  std::vector<NodePair> springs;                   // the best genome's springs
  Evaluation evaluation;                           // of the best genome, per load case
  std::optional<TopologyDifference> difference;    // against the reference, when known
  int generations = 0;                             // bred after the initial population
  int best_generation = 0;                         // when the best was found
  EvaluationCounters counters;
  double wall_seconds = 0.0;
  std::vector<TraceRow> trace;
  // Strategy hybrid: the direct phase that seeded the GA (absent on a resumed run: it ran
  // before the checkpoint).
  struct DirectPhase {
    double seconds = 0.0;
    double normalized_error = 0.0;  // of the direct topology (training stiffness)
    std::optional<TopologyDifference> difference;
  };
  std::optional<DirectPhase> direct_phase;
  // What the load cases can and cannot tell apart, analysed before the search.
  IdentifiabilityReport identifiability;
  // An FEM reference: the closed-form MSS of its mesh, evaluated before the search (the model
  // an identification must beat, engine/fem/closed_form_baseline.h).
  std::optional<fem::BaselineReport> baseline;

  // nullopt when the reference topology is unknown.
  std::optional<bool> exact() const {
    if (!difference) return std::nullopt;
    return difference->hamming() == 0;
  }
};

struct RunOptions {
  // Threads for the fitness evaluations when `pool` is null (1 = the calling thread only).
  int threads = 1;
  WorkerPool* pool = nullptr;  // a shared pool (a daemon's); must outlive the run
  bool use_cache = true;       // false: solve every genome (the results are the same)
  // After the initial population and after every generation, with the new trace row and the
  // search (for its state). Return false to stop: the result is the best so far.
  std::function<bool(const TraceRow&, const GeneticSearch&)> on_generation;
  // Continue a checkpointed run instead of starting one; `trace` is the trace so far.
  std::optional<SearchState> resume_from;
  std::vector<TraceRow> trace;
};

SearchResult RunSearch(const Problem& problem, const SearchOptions& options, const RunOptions& run = {});

}  // namespace springfit
