// Evaluates a batch of genomes (a generation, or the neighbours a local search tries) in
// parallel and returns their fitness in input order.
//
// A genome found in the cache, or repeated earlier in the same batch, is not solved again.
// Each worker slot owns its CostFunction; an evaluation starts from the reference's
// equilibrium and depends on nothing else, so the fitness of a genome is the same whichever
// thread computes it and whatever was computed before: results, hit counts and cache
// contents do not depend on the number of threads.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "engine/api/checkpoint.h"
#include "engine/api/problem.h"
#include "engine/problem/cost.h"
#include "engine/runtime/interruption.h"
#include "engine/runtime/worker_pool.h"
#include "engine/search/fitness_cache.h"

namespace springfit {

class FitnessEvaluator {
 public:
  // `pool` runs the evaluations (nullptr: the calling thread alone); it must outlive this.
  // `use_cache` = false solves every genome (to check that the cache changes nothing).
  FitnessEvaluator(const Problem& problem, WorkerPool* pool,
                   std::size_t cache_capacity = FitnessCache::kDefaultCapacity,
                   bool use_cache = true);

  // Throws Interrupted when the interruption stops the batch (nothing of it is cached).
  std::vector<Fitness> Evaluate(const std::vector<Genome>& genomes);
  // Checked before each genome and inside its solves (nullptr: never stopped); must outlive
  // the evaluations.
  void set_interruption(Interruption* interruption);

  const EvaluationCounters& counters() const { return counters_; }
  void set_counters(const EvaluationCounters& counters) { counters_ = counters; }
  FitnessCache& cache() { return cache_; }
  // A full evaluation (per load case, solver statistics), on the calling thread.
  Evaluation EvaluateInDetail(const Genome& genome) {
    return costs_.front()->EvaluateGenome(genome);
  }

 private:
  const Problem* problem_;
  WorkerPool* pool_;
  bool use_cache_;
  FitnessCache cache_;
  EvaluationCounters counters_;
  std::vector<std::unique_ptr<CostFunction>> costs_;  // one per worker slot
  Interruption* interruption_ = nullptr;
};

}  // namespace springfit
