#include "engine/search/search_options.h"

#include <algorithm>

namespace springfit {

SearchOptions StrategyDefaults(Strategy strategy, int genes) {
  SearchOptions o;  // the paper's GA
  o.strategy = strategy;
  o.identify =
      strategy == Strategy::kDirect ? Identify::kTopologyAndStiffness : Identify::kTopology;
  if (strategy == Strategy::kPaper) return o;
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
  return o;
}

}  // namespace springfit
