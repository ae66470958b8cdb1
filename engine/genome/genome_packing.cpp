#include "engine/api/checkpoint.h"

namespace springfit {

std::string PackGenome(const Genome& genome) {
  std::string packed((genome.size() + 7) / 8, '\0');
  for (std::size_t i = 0; i < genome.size(); ++i) {
    if (genome[i]) packed[i / 8] = static_cast<char>(packed[i / 8] | (1 << (i % 8)));
  }
  return packed;
}

Genome UnpackGenome(const std::string& packed, int genes) {
  Genome genome(genes, 0);
  for (int i = 0; i < genes && static_cast<std::size_t>(i / 8) < packed.size(); ++i) {
    genome[i] = static_cast<std::uint8_t>((packed[i / 8] >> (i % 8)) & 1);
  }
  return genome;
}

}  // namespace springfit
