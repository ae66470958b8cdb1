// The engine's public surface (engine/api/): what a checkpoint and the stores keep of a search:
// its state (to resume from), what it keeps of each evaluation, and genomes in their packed
// byte form. The machinery that advances a search is internal (engine/search/).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "engine/api/model.h"
#include "engine/api/problem.h"

namespace springfit {

// A genome packed 8 genes per byte (gene i in bit i % 8 of byte i / 8): the GA cache's key,
// and the form in which checkpoints and both stores keep genomes on disk. One format, here
// (engine/genome/genome_packing.cpp): changing it changes every stored job's bytes.
std::string PackGenome(const Genome& genome);
// The genome of `packed`, `genes` long (bits beyond the packed bytes are 0).
Genome UnpackGenome(const std::string& packed, int genes);

// What the search keeps of one evaluation: the numbers selection and the trace need.
struct Fitness {
  double cost = 0.0;              // f (engine/problem/cost.h), in the scene's squared length unit
  double normalized_error = 0.0;  // e = f / sum |u^R|^2, unit-free; what selection uses
  int mechanism_modes = 0;
  bool mechanism = false;
  bool converged = true;

  // A non-finite error (which the cost function should never produce) becomes the worst
  // finite value, so that comparisons stay a strict weak order.
  static Fitness From(const Evaluation& e) {
    if (!std::isfinite(e.normalized_error) || !std::isfinite(e.cost)) {
      return {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
              e.mechanism_modes, e.mechanism, false};
    }
    return {e.cost, e.normalized_error, e.mechanism_modes, e.mechanism, e.converged};
  }
  friend bool operator==(const Fitness&, const Fitness&) = default;
};

// What a search is and has been, apart from the search that advances it: the counters of its
// evaluations and everything it carries between generations (what a checkpoint keeps and a
// run resumes from). The machinery that advances it is engine/search/genetic_search.h.
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
