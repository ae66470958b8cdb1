// Checkpoints decode to the state that was encoded, field by field and bit for bit, and encode
// again to the same bytes: real snapshots of a search, and hand-made states with the edge
// values (genes not a multiple of 8, empty and non-empty genomes, -0.0, denormals, infinity,
// binary keys and random state) that checkpoint_codec_test.cpp does not reach.
#include "server/jobs/checkpoint_codec.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "engine/identification/identify.h"
#include "engine/search/fitness_cache.h"
#include "io/example_catalog.h"

namespace springfit::server {
namespace {

std::uint64_t Bits(double x) {
  return std::bit_cast<std::uint64_t>(x);
}

// Equal in every field, doubles compared bit for bit (so -0.0 is not 0.0).
void ExpectSameFitness(const Fitness& a, const Fitness& b, const std::string& what) {
  EXPECT_EQ(Bits(a.cost), Bits(b.cost)) << what << ".cost " << a.cost << " vs " << b.cost;
  EXPECT_EQ(Bits(a.normalized_error), Bits(b.normalized_error))
      << what << ".normalized_error " << a.normalized_error << " vs " << b.normalized_error;
  EXPECT_EQ(a.mechanism_modes, b.mechanism_modes) << what;
  EXPECT_EQ(a.mechanism, b.mechanism) << what;
  EXPECT_EQ(a.converged, b.converged) << what;
}

void ExpectSameState(const SearchState& a, const SearchState& b) {
  EXPECT_EQ(a.generation, b.generation);
  EXPECT_EQ(a.random_state, b.random_state);
  EXPECT_EQ(a.population, b.population);
  ASSERT_EQ(a.fitness.size(), b.fitness.size());
  for (std::size_t i = 0; i < a.fitness.size(); ++i)
    ExpectSameFitness(a.fitness[i], b.fitness[i], "fitness[" + std::to_string(i) + "]");
  EXPECT_EQ(a.best, b.best);
  ExpectSameFitness(a.best_fitness, b.best_fitness, "best_fitness");
  EXPECT_EQ(a.best_generation, b.best_generation);
  EXPECT_EQ(a.stall, b.stall);
  EXPECT_EQ(a.local_optimum, b.local_optimum);
  EXPECT_EQ(a.counters, b.counters);
  EXPECT_EQ(Bits(a.elapsed_seconds), Bits(b.elapsed_seconds));
}

// Decodes what `state` encodes to, compares, and re-encodes: the same bytes.
void ExpectRoundTrip(const SearchState& state, int genes, std::uint64_t fingerprint) {
  const std::string bytes = EncodeCheckpoint(state, genes, fingerprint);
  const SearchState decoded = DecodeCheckpoint(bytes, genes, fingerprint);
  ExpectSameState(decoded, state);
  EXPECT_EQ(EncodeCheckpoint(decoded, genes, fingerprint), bytes);
}

TEST(CheckpointRoundTrip, SnapshotsOfARealSearchDecodeExactlyAndReencodeByteForByte) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  SearchSettings settings;
  settings.strategy = Strategy::kPaper;
  settings.seed = 4;
  settings.max_generations = 40;
  const SearchOptions options = ResolveSearchOptions(settings, p.gene_count());
  const std::uint64_t fingerprint = OptionsFingerprint(options);
  std::vector<SearchState> snapshots;
  RunContext run;
  run.on_iteration = [&](const TraceRow& row, const IterationState& state) {
    if (row.generation % 7 == 0 && state.snapshot) snapshots.push_back(state.snapshot());
    return true;
  };
  const IdentificationResult result = RunIdentification(p, options, run);
  EXPECT_FALSE(result.trace.empty());
  ASSERT_GE(snapshots.size(), 2u) << "the search ended before generation 7";
  for (const SearchState& s : snapshots) {
    SCOPED_TRACE("generation " + std::to_string(s.generation));
    EXPECT_FALSE(s.population.empty());
    ExpectRoundTrip(s, p.gene_count(), fingerprint);
  }
}

TEST(CheckpointRoundTrip, EdgeValuesSurviveBitForBit) {
  constexpr int kGenes = 13;  // not a multiple of 8: the last byte of a genome is part padding
  Genome ends(kGenes, 0);
  ends[0] = 1;
  ends[kGenes - 1] = 1;
  const Genome ones(kGenes, 1);
  const Genome zeros(kGenes, 0);
  const double inf = std::numeric_limits<double>::infinity();
  const double tiny = std::numeric_limits<double>::denorm_min();

  SearchState s;
  s.generation = std::numeric_limits<int>::max();
  s.random_state = std::string("12 34\n\0 56 ", 11);  // text with a NUL and a newline
  s.population = {ends, ones, zeros};
  s.fitness = {
      {-0.0, tiny, 0, false, true},
      {inf, std::numeric_limits<double>::max(), std::numeric_limits<int>::max(), true, false},
      {std::numeric_limits<double>::lowest(), 1.0 / 3.0, -1, true, true}};
  s.best = ones;
  s.best_fitness = {0.1, 0.2, 3, false, true};
  s.best_generation = 123456;
  s.stall = 99;
  s.local_optimum = ends;
  s.counters = {std::numeric_limits<std::int64_t>::max(), 7};
  s.elapsed_seconds = 86400.000000001;
  ExpectRoundTrip(s, kGenes, 0xfedcba9876543210ULL);
  const SearchState d = DecodeCheckpoint(EncodeCheckpoint(s, kGenes, 7), kGenes, 7);
  EXPECT_EQ(d.local_optimum, ends) << "the last genome the local search proved optimal is kept";
  EXPECT_TRUE(std::signbit(d.fitness[0].cost));
}

TEST(CheckpointRoundTrip, EmptyPartsStayEmptyAndNonEmptyOnesStayNonEmpty) {
  // A fresh state: no population, no best, no local optimum.
  ExpectRoundTrip(SearchState{}, 20, 1);
  const SearchState fresh = DecodeCheckpoint(EncodeCheckpoint(SearchState{}, 20, 1), 20, 1);
  EXPECT_TRUE(fresh.population.empty());
  EXPECT_TRUE(fresh.best.empty());
  EXPECT_TRUE(fresh.local_optimum.empty());

  // No best yet but a local optimum, and the other way round: each genome has its own flag.
  SearchState a;
  a.local_optimum = Genome(20, 1);
  ExpectRoundTrip(a, 20, 1);
  SearchState b;
  b.best = Genome(20, 1);
  ExpectRoundTrip(b, 20, 1);
  const SearchState db = DecodeCheckpoint(EncodeCheckpoint(b, 20, 1), 20, 1);
  EXPECT_EQ(db.best, Genome(20, 1));
  EXPECT_TRUE(db.local_optimum.empty());

  // One gene.
  SearchState one;
  one.population = {Genome{1}, Genome{0}};
  one.fitness = std::vector<Fitness>(2);
  one.best = Genome{1};
  one.local_optimum = Genome{0};
  ExpectRoundTrip(one, 1, 1);
}

}  // namespace
}  // namespace springfit::server
