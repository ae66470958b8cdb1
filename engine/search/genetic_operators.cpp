#include "engine/search/genetic_operators.h"

#include <cmath>
#include <stdexcept>
#include <utility>

#include "engine/api/search_options.h"

namespace springfit {

double RouletteWeight(double normalized_error, double exponent) {
  const double e = normalized_error + kExactNormalizedError;
  // 1 / e exactly for the paper strategy's exponent, whatever pow's rounding.
  return exponent == 1.0 ? 1.0 / e : std::pow(e, -exponent);
}

int RouletteSelect(std::span<const double> weights, RandomStream& random) {
  if (weights.empty()) throw std::invalid_argument("RouletteSelect: no weights");
  double total = 0.0;
  for (double w : weights) total += w;
  const int n = static_cast<int>(weights.size());
  if (!(total > 0.0)) return random.Below(n);
  const double target = random.Uniform() * total;
  double cumulative = 0.0;
  for (int i = 0; i < n; ++i) {
    cumulative += weights[i];
    if (target < cumulative) return i;
  }
  // Round-off can leave target a hair above the last partial sum: the last positive weight.
  for (int i = n - 1; i > 0; --i) {
    if (weights[i] > 0.0) return i;
  }
  return 0;
}

int TournamentSelect(std::span<const double> errors, int size, RandomStream& random) {
  if (errors.empty() || size < 1) throw std::invalid_argument("TournamentSelect: empty");
  const int n = static_cast<int>(errors.size());
  int winner = random.Below(n);
  for (int t = 1; t < size; ++t) {
    const int challenger = random.Below(n);
    if (errors[challenger] < errors[winner]) winner = challenger;
  }
  return winner;
}

int OnePointCrossover(Genome& a, Genome& b, RandomStream& random) {
  if (a.size() != b.size()) throw std::invalid_argument("OnePointCrossover: genome sizes differ");
  const int n = static_cast<int>(a.size());
  if (n < 2) return 0;
  const int cut = 1 + random.Below(n - 1);
  for (int i = cut; i < n; ++i) std::swap(a[i], b[i]);
  return cut;
}

void UniformCrossover(Genome& a, Genome& b, RandomStream& random) {
  if (a.size() != b.size()) throw std::invalid_argument("UniformCrossover: genome sizes differ");
  for (std::size_t i = 0; i < a.size(); ++i) {
    // One bit per gene from the stream, drawn in gene order.
    if (random.NextBits() >> 63) std::swap(a[i], b[i]);
  }
}

int BitFlipMutation(Genome& genome, double p, RandomStream& random) {
  int flips = 0;
  for (std::uint8_t& gene : genome) {
    if (random.Bernoulli(p)) {
      gene ^= 1;
      ++flips;
    }
  }
  return flips;
}

Genome RandomGenome(int genes, double density, RandomStream& random) {
  Genome genome(genes);
  for (std::uint8_t& gene : genome) gene = random.Bernoulli(density) ? 1 : 0;
  return genome;
}

}  // namespace springfit
