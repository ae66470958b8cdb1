// The topology search: a generational genetic algorithm, optionally memetic (search_options.h
// says what each strategy switches on), advanced one generation at a time.
//
// Determinism: every random draw is made on the calling thread, in an order fixed by the
// algorithm; only the fitness evaluations of a batch run in parallel (FitnessEvaluator), and
// they are pure. The same problem, options and seed give the same trace (wall time aside)
// and result with any number of threads. The whole state between generations is in
// SearchState, so a run can be checkpointed and resumed to the same end.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "engine/api/checkpoint.h"
#include "engine/api/problem.h"
#include "engine/api/search_options.h"
#include "engine/runtime/trace.h"
#include "engine/search/fitness_evaluator.h"
#include "engine/search/random_stream.h"

namespace springfit {

class GeneticSearch {
 public:
  // `evaluator` must outlive the search and belong to the same problem.
  GeneticSearch(const Problem& problem, SearchOptions options, FitnessEvaluator& evaluator);

  // Draws and evaluates the initial population (generation 0). Genomes given to
  // SeedInitialPopulation take the first places; the rest are drawn as usual.
  TraceRow Initialize();
  // Before Initialize(): start from these genomes (strategy hybrid seeds the direct result),
  // with `elapsed_seconds` of earlier phases on the trace's clock.
  void SeedInitialPopulation(std::vector<Genome> genomes, double elapsed_seconds);
  // Continues from a saved state instead of Initialize().
  void Restore(const SearchState& state);
  // Breeds and evaluates one generation (and runs the local search when enabled).
  TraceRow Step();

  bool TargetReached() const;
  bool Finished() const {
    return (options_.stop_at_target && TargetReached()) ||
           state_.generation >= options_.max_generations || Stalled() || TimeLimitReached();
  }
  // The best has not improved for stall_generations generations.
  bool Stalled() const {
    return options_.stall_generations > 0 && state_.stall >= options_.stall_generations;
  }
  bool TimeLimitReached() const {
    return options_.max_seconds > 0.0 && ElapsedSeconds() >= options_.max_seconds;
  }

  // Checked between batches of evaluations (after the population's, before every batch of
  // local-search moves) and, through the evaluator, inside them: a stop abandons the current
  // step. A local search stopped mid-batch keeps what it had found; a population stopped
  // mid-evaluation throws Interrupted out of Initialize() or Step(). The state is then
  // mid-step: good for a best-so-far result, not for a checkpoint (Interrupted() says so).
  // Must outlive the search.
  void set_interruption(Interruption* interruption) { interruption_ = interruption; }
  bool Interrupted() const {
    return interrupted_ || (interruption_ != nullptr && interruption_->requested());
  }

  // The state between generations, random stream included (for a checkpoint).
  SearchState Snapshot() const;
  const SearchState& state() const { return state_; }
  const SearchOptions& options() const { return options_; }
  // Wall time of the run, including the time before a Restore().
  double ElapsedSeconds() const;

  // Per gene, the genes the local search may swap it with (search_options.h, swap_radius).
  static std::vector<std::vector<int>> SwapPartners(const Problem& problem, double radius);

 private:
  // Individual i of an initial (or restarted) population, drawn at its density.
  Genome InitialGenome(int i);
  // The normalised error at which the search has reached its target.
  double TargetError() const;
  std::vector<Genome> Breed();
  int Select(const std::vector<double>& weights_or_errors);
  void LocalSearch();
  // The individual a local search starts from.
  int LocalSearchStart() const;
  // Evaluates the batch's improving moves made at once, `combined`, and makes it `next` when
  // better than `next_fitness` (false when not, or interrupted).
  bool TryCombined(Genome combined, Genome& next, Fitness& next_fitness);
  void UpdateBest();
  TraceRow Row() const;

  const Problem* problem_;
  SearchOptions options_;
  FitnessEvaluator* evaluator_;
  RandomStream random_;
  SearchState state_;
  std::vector<std::vector<int>> swap_partners_;
  std::chrono::steady_clock::time_point started_;
  double elapsed_before_ = 0.0;  // wall time of the run before a Restore() or a seeding phase
  Interruption* interruption_ = nullptr;
  bool interrupted_ = false;
  // Checks the interruption (once interrupted, stays so).
  bool PollInterrupt();
};

}  // namespace springfit
