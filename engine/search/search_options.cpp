#include "engine/api/search_options.h"

#include <algorithm>
#include <cmath>

#include "engine/runtime/options_check.h"

namespace springfit {

void SearchOptions::Validate() const {
  const OptionsCheck check("SearchOptions");
  const auto probability = [](double p) { return p >= 0.0 && p <= 1.0; };
  check.Require(population >= 2, "population", population, "value >= 2");
  check.Require(max_generations >= 0, "max_generations", max_generations, "value >= 0");
  check.Require(max_seconds >= 0.0 && std::isfinite(max_seconds), "max_seconds", max_seconds,
                "0 <= value < infinity (0: no limit)");
  check.Require(stall_generations >= 0, "stall_generations", stall_generations,
                "value >= 0 (0: never)");
  check.Require(target_normalized_error >= 0.0 && std::isfinite(target_normalized_error),
                "target_normalized_error", target_normalized_error, "0 <= value < infinity");
  check.Require(tournament_size >= 1 && tournament_size <= population, "tournament_size",
                tournament_size, "1 <= value <= population");
  check.Require(roulette_exponent > 0.0 && roulette_exponent <= kMaxRouletteExponent,
                "roulette_exponent", roulette_exponent, "0 < value <= 10");
  check.Require(probability(crossover_probability), "crossover_probability", crossover_probability,
                "0 <= value <= 1");
  check.Require(probability(mutation_probability), "mutation_probability", mutation_probability,
                "0 <= value <= 1");
  check.Require(elites >= 0 && elites < population, "elites", elites, "0 <= value < population");
  check.Require(probability(initial_density_low), "initial_density_low", initial_density_low,
                "0 <= value <= 1");
  check.Require(probability(initial_density_high) && initial_density_high >= initial_density_low,
                "initial_density_high", initial_density_high, "initial_density_low <= value <= 1");
  check.Require(local_search_batch >= 1, "local_search_batch", local_search_batch, "value >= 1");
  check.Require(swap_radius >= 0.0 && std::isfinite(swap_radius), "swap_radius", swap_radius,
                "0 <= value < infinity");
  check.Require(max_springs >= 0, "max_springs", max_springs, "value >= 0 (0: no limit)");
  check.Require(target_error >= 0.0 && std::isfinite(target_error), "target_error", target_error,
                "0 <= value < infinity (0: none)");
  check.Require(load_size >= 0.0 && std::isfinite(load_size), "load_size", load_size,
                "finite value >= 0 (0: the named loads' size)");
  check.Require(max_spread == 0.0 || (max_spread > 1.0 && std::isfinite(max_spread)), "max_spread",
                max_spread, "value > 1 (0: none)");
  check.Require(regularization >= 0.0 && std::isfinite(regularization), "regularization",
                regularization, "0 <= value < infinity (0: none)");
  check.Require(probes >= kAutomaticProbes && probes <= kMaxProbes, "probes", probes,
                "-1 (automatic), 0 (none) or 1 <= value <= 20000");
  check.Require(cache_capacity >= 1, "cache_capacity", static_cast<double>(cache_capacity),
                "value >= 1");
}

SearchOptions StrategyDefaults(Strategy strategy, int genes) {
  SearchOptions o;  // the paper's GA
  o.strategy = strategy;
  o.identify = strategy == Strategy::kDirect || strategy == Strategy::kContinuous
                   ? Identify::kTopologyAndStiffness
                   : Identify::kTopology;
  if (strategy == Strategy::kPaper || strategy == Strategy::kContinuous) return o;
  o.selection = SearchOptions::Selection::kTournament;
  o.tournament_size = 2;
  o.crossover = SearchOptions::Crossover::kUniform;
  o.crossover_probability = 0.9;
  o.mutation_probability = 1.0 / std::max(genes, 1);
  o.elites = 1;
  o.initial_density_low = 0.5;
  o.initial_density_high = 1.0;
  o.local_search = true;
  o.stall_generations = 200;
  return o;
}

SearchOptions ResolveSearchOptions(const SearchSettings& settings, int genes) {
  SearchOptions o = StrategyDefaults(settings.strategy, genes);
  if (settings.identify)
    o.identify = *settings.identify;  // scene validation checked it fits the strategy
  o.seed = settings.seed;
  if (settings.population) o.population = *settings.population;
  if (settings.crossover_probability) o.crossover_probability = *settings.crossover_probability;
  if (settings.mutation_probability) o.mutation_probability = *settings.mutation_probability;
  o.max_generations = settings.max_generations;
  o.target_normalized_error = settings.target_normalized_error;
  if (settings.max_seconds) o.max_seconds = *settings.max_seconds;
  if (settings.stall_generations) o.stall_generations = *settings.stall_generations;
  if (settings.max_springs) o.max_springs = *settings.max_springs;
  if (settings.target_error) o.target_error = *settings.target_error;
  if (settings.max_spread) o.max_spread = *settings.max_spread;
  if (settings.load_size) o.load_size = *settings.load_size;
  if (settings.regularization) {
    o.choose_regularization = settings.regularization->automatic;
    o.regularization = settings.regularization->strength;
  }
  if (settings.probes) o.probes = *settings.probes;
  return o;
}

}  // namespace springfit
