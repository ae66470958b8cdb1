// Genomes already evaluated, and their fitness: a genetic population repeats itself a lot
// (unchanged parents, crossover of equal halves, no mutation), and an evaluation is pure,
// so a repeat is looked up instead of solved.
//
// Bounded: beyond `capacity` entries the oldest insertion is evicted (first in, first out).
// Eviction depends only on the order of insertions, which the search makes deterministic,
// so hit counts are reproducible. Its contents can be listed and reloaded for a checkpoint.
#pragma once

#include <cstddef>
#include <deque>
#include <optional>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "engine/api/checkpoint.h"
#include "engine/api/problem.h"
#include "engine/api/search_options.h"

namespace springfit {

class FitnessCache {
 public:
  // About 100 bytes per entry plus the packed genome (genes / 8 bytes).
  static constexpr std::size_t kDefaultCapacity = kDefaultFitnessCacheCapacity;

  explicit FitnessCache(std::size_t capacity = kDefaultCapacity) : capacity_(capacity) {}

  // Keys are packed genomes (engine/api/checkpoint.h).
  static std::string Key(const Genome& genome) { return PackGenome(genome); }

  std::optional<Fitness> Find(const std::string& key) const;
  // No-op when the key is present; evicts the oldest entry when full.
  void Insert(const std::string& key, const Fitness& fitness);

  void Clear() {
    entries_.clear();
    order_.clear();
  }
  std::size_t size() const { return entries_.size(); }
  std::size_t capacity() const { return capacity_; }

 private:
  std::size_t capacity_;
  std::unordered_map<std::string, Fitness> entries_;
  std::deque<std::string> order_;
};

}  // namespace springfit
