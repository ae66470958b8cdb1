// The engine's public surface (engine/api/), and its one entry point for an identification:
// `springfit run`, the daemon and the benchmarks call RunIdentification() and read one
// IdentificationResult, whatever the strategy.
//
// RunIdentification() analyses the prepared problem (identifiability, the closed-form baseline of
// an FEM reference) before the run's clock starts, runs the strategy that SearchOptions::strategy
// names (strategy.h: the one place that maps strategies to code), and fills the parts of the
// result every strategy shares (springs, stiffness, difference to the reference).
//
// A request the run cannot meet (too few probes, more memory than the machine has: run_bounds.h)
// throws InputError before any work.
//
// Control: every phase reports beats and can be stopped within about a second (run_monitor.h).
// A run stopped before it had evaluated any model (during the analysis, the direct phase or the
// first population's evaluation without a seed) returns the empty topology, stop kCancelled or
// kTimeLimit, and an empty trace.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string_view>
#include <vector>

#include "engine/api/checkpoint.h"
#include "engine/api/problem.h"
#include "engine/api/result.h"
#include "engine/api/search_options.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/wall_clock.h"
#include "engine/runtime/worker_pool.h"

namespace springfit {

// What a run reports to its caller after each iteration.
struct IterationState {
  bool finished = false;         // the strategy has nothing more to do (target, limit, single shot)
  const Genome* best = nullptr;  // the best model so far
  // The state to checkpoint; empty for a strategy that cannot resume (direct).
  std::function<SearchState()> snapshot;
};

// Between iterations: where a long step has got to (RunContext::on_beat).
struct ProgressBeat {
  // "direct" (the force-balance solve of strategies direct and hybrid), "genetic"; strategy
  // continuous on the named cases: "regularization", "fit" (`evaluations` accepted steps, the
  // last one's error), "path" (the sparsity path: `generation` points so far, the last one's
  // error), "refit" and "held_out"; fitted to probes: "probes" (the banks), "probe_fit",
  // "probe_path", "probe_lift", "nonlinear_fit", "certificate" and "nonlinear"
  // (the judgement as the simulator runs it). proto/RPC.md (job.phase) lists them too.
  std::string_view phase;
  double wall_seconds = 0.0;  // on the run's clock
  int generation = 0;         // the generation in progress
  std::int64_t evaluations = 0;
  double best_normalized_error = 0.0;  // of the best model so far
  // The phase's estimate of the seconds it has left, at most; NaN where it has none. The probe
  // fit's "probe_fit": its continuation's steps left at the pace of those it made.
  double eta_seconds = std::numeric_limits<double>::quiet_NaN();
};

struct RunContext {
  // Threads for the fitness evaluations when `pool` is null (1 = the calling thread only).
  int threads = 1;
  WorkerPool* pool = nullptr;  // a shared pool (a daemon's); must outlive the run
  bool use_cache = true;       // false: solve every genome (the results are the same)
  // After every iteration (the initial population, every generation, a direct solve), with
  // its trace row. Return false to stop: the result is the best so far, stop kCancelled.
  std::function<bool(const TraceRow&, const IterationState&)> on_iteration;
  // Inside every phase, about every `beat_seconds` of wall time without an iteration's report
  // (the checks sit between Newton iterations, NNLS rounds and evaluations, each well under a
  // second on the examples: bench/RESULTS.md): progress for a live display, and a chance to
  // stop. Return false to stop at once: the step is abandoned (no checkpoint can be taken of
  // it), the result is the best so far, stop kCancelled. Called on the thread that called
  // RunIdentification().
  std::function<bool(const ProgressBeat&)> on_beat;
  // Stop requests (on_beat's answer, the time limit) are read this often too: a quarter of a
  // second keeps a stop within a second even behind a unit of work of half a second.
  double beat_seconds = 0.25;
  // When the run began for its user: before its scene was read and prepared (a command's
  // start, a job's claim). The time limit (SearchOptions::max_seconds) counts from here, so
  // that it bounds what the user waits; unset, from the call of RunIdentification().
  std::optional<std::chrono::steady_clock::time_point> started;
  // The share of the machine's memory this run may hold, in (0, 1]: a daemon running several
  // jobs at once gives each its part of the half a run has alone. The nonlinear fit bounds
  // itself by it (engine/probe_fit/nonlinear_response.h, NonlinearFitOptions::max_bytes).
  double memory_share = 0.5;
  // Continue a checkpointed genetic run instead of starting one; `trace` is the trace so far.
  std::optional<SearchState> resume_from;
  std::vector<TraceRow> trace;
};

IdentificationResult RunIdentification(const Problem& problem, const SearchOptions& options,
                                       const RunContext& context = {});

// Throws InputError before any work (engine/identification/run_bounds.cpp), naming
// search.probes, when an explicit probe count is below what gives every (support, family)
// group a fitted, a choosing and a held-out probe (MinimumProbeCount), or when ProbeFitBytes
// exceeds `available_bytes` (<= 0: half the machine's physical memory).
void CheckRunBounds(const Problem& problem, const SearchOptions& options,
                    double available_bytes = 0.0);

}  // namespace springfit
