// The genetic algorithm's operators on bit-string genomes. Each takes the random stream
// explicitly, so the order of draws (and with it the run) is fixed by the caller.
#pragma once

#include <span>

#include "engine/api/problem.h"
#include "engine/search/random_stream.h"

namespace springfit {

// Roulette-wheel (fitness-proportional) selection: index i with probability
// weights[i] / sum(weights). Weights must be finite and >= 0; all zero selects uniformly.
int RouletteSelect(std::span<const double> weights, RandomStream& random);
// The roulette weight of an individual of normalised error e: (e + kExactNormalizedError)^-p.
// Unit-free (e is), finite for an exact topology, and graded among mechanisms.
double RouletteWeight(double normalized_error, double exponent);

// Tournament selection: `size` indices drawn uniformly with replacement; the one with the
// smallest error wins (ties: the first drawn).
int TournamentSelect(std::span<const double> errors, int size, RandomStream& random);

// One-point crossover: draws a cut point c uniformly in [1, n-1] and swaps the genes at and
// after c between a and b. Returns c (0 when the genomes have fewer than two genes: no-op).
int OnePointCrossover(Genome& a, Genome& b, RandomStream& random);

// Uniform crossover: each gene is swapped between a and b with probability 1/2.
void UniformCrossover(Genome& a, Genome& b, RandomStream& random);

// Bit-flip mutation: each gene flips with probability p. Returns the number of flips.
int BitFlipMutation(Genome& genome, double p, RandomStream& random);

// A random genome whose genes are 1 with probability `density`.
Genome RandomGenome(int genes, double density, RandomStream& random);

}  // namespace springfit
