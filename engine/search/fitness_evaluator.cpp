#include "engine/search/fitness_evaluator.h"

#include <algorithm>
#include <atomic>
#include <unordered_map>

namespace springfit {

FitnessEvaluator::FitnessEvaluator(const Problem& problem, WorkerPool* pool,
                                   std::size_t cache_capacity, bool use_cache)
    : problem_(&problem), pool_(pool), use_cache_(use_cache), cache_(cache_capacity) {
  const int slots = pool ? pool->threads() : 1;
  for (int s = 0; s < slots; ++s) costs_.push_back(std::make_unique<CostFunction>(problem));
}

void FitnessEvaluator::set_interruption(Interruption* interruption) {
  interruption_ = interruption;
  for (const auto& cost : costs_) cost->set_interruption(interruption);
}

std::vector<Fitness> FitnessEvaluator::Evaluate(const std::vector<Genome>& genomes) {
  const int n = static_cast<int>(genomes.size());
  std::vector<Fitness> out(n);
  // Which genomes need a solve: not cached, and not an earlier genome of this batch.
  std::vector<int> to_solve;
  std::vector<int> same_as(n, -1);
  std::vector<std::string> keys(n);
  std::unordered_map<std::string, int> first_in_batch;
  EvaluationCounters batch;  // added once the batch is complete
  for (int i = 0; i < n; ++i) {
    ++batch.evaluations;
    if (!use_cache_) {
      to_solve.push_back(i);
      continue;
    }
    keys[i] = FitnessCache::Key(genomes[i]);
    if (const auto hit = cache_.Find(keys[i])) {
      out[i] = *hit;
      ++batch.cache_hits;
    } else if (const auto [it, inserted] = first_in_batch.emplace(keys[i], i); !inserted) {
      same_as[i] = it->second;
      ++batch.cache_hits;
    } else {
      to_solve.push_back(i);
    }
  }

  std::atomic<int> next{0};
  auto work = [&](int slot) {
    CostFunction& cost = *costs_[slot];
    for (int t = next.fetch_add(1); t < static_cast<int>(to_solve.size()); t = next.fetch_add(1)) {
      if (interruption_ && interruption_->Check()) return;
      out[to_solve[t]] = Fitness::From(cost.EvaluateGenome(genomes[to_solve[t]]));
    }
  };
  const int slots = std::min(static_cast<int>(costs_.size()), static_cast<int>(to_solve.size()));
  if (pool_ && slots > 1) {
    pool_->Run(slots, work, [this] {
      if (interruption_) interruption_->Check();
    });
  } else if (!to_solve.empty()) {
    work(0);
  }
  // Some genomes of the batch went unevaluated, or were cut short: none of it is kept.
  if (interruption_ && interruption_->requested()) throw Interrupted();
  counters_.evaluations += batch.evaluations;
  counters_.cache_hits += batch.cache_hits;

  for (int i = 0; i < n; ++i) {
    if (same_as[i] >= 0) out[i] = out[same_as[i]];
  }
  if (use_cache_) {
    for (int i : to_solve) cache_.Insert(keys[i], out[i]);
  }
  return out;
}

}  // namespace springfit
