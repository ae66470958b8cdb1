// What a search is and has been, apart from the search that advances it: the counters of its
// evaluations and everything it carries between generations (what a checkpoint keeps and a
// run resumes from). The machinery that advances it is genetic_search.h.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/genome/genome.h"
#include "engine/search/fitness.h"

namespace springfit {

struct EvaluationCounters {
  std::int64_t evaluations = 0;  // genomes asked for
  std::int64_t cache_hits = 0;   // of those, answered without a solve
  friend bool operator==(const EvaluationCounters&, const EvaluationCounters&) = default;
};

// Everything a search carries from one generation to the next. The random stream, the
// counters and the elapsed time live in their owners while the search runs;
// GeneticSearch::Snapshot() copies them in. The fitness cache is not part of it: a genome's
// fitness does not depend on it (FitnessEvaluator), so a restored search finds the same
// genomes, errors and best as an uninterrupted one, with fewer cache hits (trace rows'
// cache_hits) until its cache fills again.
struct SearchState {
  int generation = 0;
  std::string random_state;  // RandomStream::SaveState()
  std::vector<Genome> population;
  std::vector<Fitness> fitness;  // of population
  Genome best;                   // best genome found so far (first found among equals)
  Fitness best_fitness;
  int best_generation = 0;
  int stall = 0;         // generations since the best last improved
  Genome local_optimum;  // last genome the local search proved locally optimal
  EvaluationCounters counters;
  double elapsed_seconds = 0.0;
  // The genomes an earlier phase seeded the initial population with, and that phase's seconds
  // (SeedInitialPopulation): a resumed run reports its seeding phase from them.
  std::vector<Genome> seeds;
  double seeded_seconds = 0.0;
};

}  // namespace springfit
