// What a topology search does, resolved from a scene's search settings: the strategy's
// defaults, overridden by whatever the scene (or the command line) sets.
//
// Strategy `paper` is the genetic algorithm of Bianchi et al. (2003) as published:
// population 20, roulette-wheel selection, one-point crossover with probability 0.3, bit-flip
// mutation with probability 0.01 per gene, a random initial population (each gene 1 with
// probability 1/2), no elitism, at most 1000 generations.
// The paper does not say how a cost becomes a roulette weight. Here the weight of an
// individual is 1 / (e + kExactNormalizedError), e its normalised error: unit-free (scaling
// the scene's lengths leaves e, hence every weight, unchanged), finite for an exact
// topology, and graded among mechanisms because their penalised e grows with their modes.
// Other powers of it and elitism, which the paper does not describe either, are variants
// for the experiments (bench/search_experiment --roulette-exponent, --elites).
//
// Strategy `hybrid` (and `default` on a reference other than FEM, what the experiments in
// bench/RESULTS.md measured fastest there, issues 3 and 4): the direct identification's topology
// (engine/direct/, topology only) seeds a memetic GA: one elite, binary tournament selection,
// uniform crossover with probability 0.9, mutation of one gene per child on average (1 / genes), an
// initial population spread in density over [0.5, 1), and in every generation a local search
// (single flips, then swaps of nearby springs) on the best new individual. For an MSS reference the
// seed is the answer and the run ends in generation 0; for noisy data the GA corrects it. On an FEM
// reference `default` is strategy continuous (engine/fit/), which reads none of these settings but
// max_springs and target_error.
#pragma once

#include <cstddef>
#include <cstdint>

#include "engine/api/scene.h"

namespace springfit {

// A normalised error at or below this counts as exact recovery (target 0). The reference
// topology evaluates to exactly 0 (its solve starts at the reference equilibrium); one
// wrong gene costs far more (tests/engine/search/search_test.cpp checks a margin of 1e3 on a
// small scene).
inline constexpr double kExactNormalizedError = 1e-12;
// The largest roulette exponent: an exact individual's weight (1e-12)^-10 = 1e120 keeps every
// weight, and the sum of a population's, finite.
inline constexpr double kMaxRouletteExponent = 10.0;
// The fitness cache's default capacity in entries (FitnessCache: about 100 bytes each plus the
// packed genome).
inline constexpr std::size_t kDefaultFitnessCacheCapacity = std::size_t{1} << 18;

struct SearchOptions {
  enum class Selection { kRoulette, kTournament };
  enum class Crossover { kOnePoint, kUniform };

  Strategy strategy = Strategy::kPaper;
  Identify identify = Identify::kTopology;
  std::uint64_t seed = 1;
  int population = 20;
  int max_generations = 1000;  // generations bred after the initial population
  // Wall seconds from the run's start after which it stops, inside the step running then, with
  // the best so far (0 = no limit; engine/identification/run_monitor.h). Unlike every other
  // stop, where it stops depends on the machine: a run stopped by it is not reproducible.
  double max_seconds = 0.0;
  // Stop when the best has not improved for this many generations (0 = never): a noisy run
  // whose best was found early does not spend its whole generation budget. `paper` has none
  // (the paper's GA ran its 1000 generations); `default` and `hybrid` stop after 200.
  int stall_generations = 0;
  double target_normalized_error = 0.0;  // stop at or below max(this, kExactNormalizedError)
  bool stop_at_target = true;            // false: run every generation (benchmarks of a full run)

  Selection selection = Selection::kRoulette;
  int tournament_size = 2;  // kTournament
  // kRoulette: individual weights (e + kExactNormalizedError)^-roulette_exponent, the exponent
  // in (0, kMaxRouletteExponent].
  double roulette_exponent = 1.0;
  Crossover crossover = Crossover::kOnePoint;
  double crossover_probability = 0.3;  // per pair of parents
  double mutation_probability = 0.01;  // per gene of every child
  int elites = 0;                      // best individuals copied unchanged into the next generation

  // Individual i of the initial population has genes 1 with probability
  // low + (high - low) * (i + 1/2) / population.
  double initial_density_low = 0.5;
  double initial_density_high = 0.5;

  // Bit-flip local search on the best new individual of a generation (every individual in
  // the initial population counts as new; elites do not): its single-gene neighbours are
  // evaluated `local_search_batch` at a time (a fixed number, so the run does not depend on
  // the thread count) and the best improving one is taken, until a whole pass over the genes
  // finds no improvement.
  // With `local_search_swaps`, a genome no single flip improves is then tried with swaps:
  // one present spring removed and one absent spring added whose midpoints lie within
  // `swap_radius` times the shorter rest length (the two diagonals of a cell; a diagonal and
  // a side). Any improvement returns to single flips; the search ends where neither helps.
  bool local_search = false;
  int local_search_batch = 16;
  // When several moves of a batch improve, also try all of them at once (one evaluation more)
  // and keep that when it is better than the best single move.
  bool local_search_combine = true;
  bool local_search_swaps = true;
  double swap_radius = 0.5;

  std::size_t cache_capacity = kDefaultFitnessCacheCapacity;

  // Strategy continuous: which point of the sparsity path to return (engine/fit/
  // sparsity_path.h, SelectPathPoint): the lowest error with at most `max_springs` springs
  // (0: no limit), else the fewest springs with E <= `target_error` (0: none), else the fewest
  // within 5% of the lowest E.
  int max_springs = 0;
  double target_error = 0.0;
  // Strategy continuous fitted to probes: the bound on the model's stiffness spread
  // (ResponseFitOptions::max_spread; 0: none).
  double max_spread = 0.0;
  // Strategy continuous fitted to probes: the load range's size, the largest nodal displacement
  // (scene length; 0: the named loads' size). SearchSettings::load_size.
  double load_size = 0.0;
  // Strategy continuous: the stiffness fits' regularisation toward the start
  // (StiffnessFitOptions::regularization), or with `choose_regularization` the one of
  // kRegularizationChoices whose held-out error is lowest.
  double regularization = 0.0;
  bool choose_regularization = false;
  // Strategy continuous on an FEM or MSS reference: the probe bank's size (SearchSettings::
  // probes): kAutomaticProbes, 0 (none: the named cases alone) or about that many probes.
  static constexpr int kAutomaticProbes = -1;
  static constexpr int kMaxProbes = 20000;
  int probes = kAutomaticProbes;

  // Throws std::invalid_argument naming the field, its value and the rule it breaks.
  void Validate() const;
};

// The strategy's defaults for a genome of `genes` genes. (Strategy default has the GA's: on an
// FEM reference it runs continuous, which reads none of them.)
SearchOptions StrategyDefaults(Strategy strategy, int genes);
// The strategy's defaults with every field the settings set applied.
SearchOptions ResolveSearchOptions(const SearchSettings& settings, int genes);

}  // namespace springfit
