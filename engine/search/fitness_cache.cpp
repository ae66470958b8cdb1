#include "engine/search/fitness_cache.h"

namespace springfit {

std::optional<Fitness> FitnessCache::Find(const std::string& key) const {
  const auto it = entries_.find(key);
  if (it == entries_.end()) return std::nullopt;
  return it->second;
}

void FitnessCache::Insert(const std::string& key, const Fitness& fitness) {
  if (capacity_ == 0 || entries_.contains(key)) return;
  if (entries_.size() >= capacity_) {
    entries_.erase(order_.front());
    order_.pop_front();
  }
  entries_.emplace(key, fitness);
  order_.push_back(key);
}

}  // namespace springfit
