#include "engine/search/fitness_cache.h"

namespace springfit {

std::string FitnessCache::Key(const Genome& genome) {
  std::string key((genome.size() + 7) / 8, '\0');
  for (std::size_t i = 0; i < genome.size(); ++i) {
    if (genome[i]) key[i / 8] = static_cast<char>(key[i / 8] | (1 << (i % 8)));
  }
  return key;
}

Genome FitnessCache::Unpack(const std::string& key, int genes) {
  Genome genome(genes, 0);
  for (int i = 0; i < genes && static_cast<std::size_t>(i / 8) < key.size(); ++i) {
    genome[i] = static_cast<std::uint8_t>((key[i / 8] >> (i % 8)) & 1);
  }
  return genome;
}

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
