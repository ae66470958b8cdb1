#include "server/jobs/checkpoint_codec.h"

#include <gtest/gtest.h>

#include "engine/identification/identify.h"
#include "io/example_catalog.h"
#include "server/version.h"

namespace springfit::server {
namespace {

SearchOptions PaperOptions(const Problem& p, std::uint64_t seed, int generations) {
  SearchSettings st;
  st.strategy = Strategy::kPaper;
  st.seed = seed;
  st.max_generations = generations;
  return ResolveSearchOptions(st, p.gene_count());
}

TEST(CheckpointCodec, ResumingFromDecodedBytesEndsExactlyLikeAnUninterruptedRun) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  const SearchOptions o = PaperOptions(p, 4, 40);
  const IdentificationResult whole = RunIdentification(p, o);
  ASSERT_EQ(whole.generations, 40);

  std::string bytes;
  RunContext first;
  first.on_iteration = [&](const TraceRow& row, const IterationState& state) {
    if (row.generation < 17) return true;
    bytes = EncodeCheckpoint(state.snapshot(), p.gene_count(), OptionsFingerprint(o));
    return false;
  };
  const IdentificationResult part = RunIdentification(p, o, first);
  ASSERT_FALSE(bytes.empty());

  const SearchState state = DecodeCheckpoint(bytes, p.gene_count(), OptionsFingerprint(o));
  EXPECT_EQ(state.generation, 17);
  RunContext second;
  second.resume_from = state;
  second.trace = part.trace;
  const IdentificationResult resumed = RunIdentification(p, o, second);
  ASSERT_EQ(resumed.trace.size(), whole.trace.size());
  // Identical but for cache hits after the resume (the checkpoint has no fitness cache): the
  // same genomes, errors and best.
  for (std::size_t i = 0; i < whole.trace.size(); ++i)
    EXPECT_TRUE(whole.trace[i].SameSearchButCacheHits(resumed.trace[i])) << i;
  EXPECT_EQ(resumed.trace[17].cache_hits, whole.trace[17].cache_hits);
  EXPECT_LT(resumed.counters.cache_hits, whole.counters.cache_hits);
  EXPECT_EQ(resumed.best, whole.best);
  EXPECT_EQ(resumed.counters.evaluations, whole.counters.evaluations);
  EXPECT_EQ(resumed.evaluation.cost, whole.evaluation.cost);
}

TEST(CheckpointCodec, RoundTripKeepsEveryField) {
  SearchState s;
  s.generation = 7;
  s.random_state = "1 2 3";
  s.population = {{1, 0, 1}, {0, 0, 1}};
  s.fitness = {{0.5, 1e-300, 2, true, false},
               {std::numeric_limits<double>::max(), 0.1, 0, false, true}};
  s.best = {1, 1, 1};
  s.best_fitness = {0.25, 0.125, 0, false, true};
  s.best_generation = 3;
  s.stall = 4;
  s.counters = {100, 40};
  s.elapsed_seconds = 1.5;
  s.seeds = {{0, 1, 1}};
  s.seeded_seconds = 0.25;
  const SearchState d = DecodeCheckpoint(EncodeCheckpoint(s, 3, 42), 3, 42);
  EXPECT_EQ(d.generation, 7);
  EXPECT_EQ(d.random_state, s.random_state);
  EXPECT_EQ(d.population, s.population);
  EXPECT_EQ(d.fitness, s.fitness);
  EXPECT_EQ(d.best, s.best);
  EXPECT_EQ(d.best_fitness, s.best_fitness);
  EXPECT_EQ(d.best_generation, 3);
  EXPECT_EQ(d.stall, 4);
  EXPECT_TRUE(d.local_optimum.empty());
  EXPECT_EQ(d.counters, s.counters);
  EXPECT_EQ(d.elapsed_seconds, 1.5);
  EXPECT_EQ(d.seeds, s.seeds);
  EXPECT_EQ(d.seeded_seconds, 0.25);
}

TEST(CheckpointCodec, CorruptOrForeignBytesAreRefused) {
  SearchState s;
  s.population = {{1, 0, 1}};
  s.fitness = {{}};
  s.best = {1, 0, 1};
  const std::string bytes = EncodeCheckpoint(s, 3, 42);
  EXPECT_NO_THROW(DecodeCheckpoint(bytes, 3, 42));
  EXPECT_THROW(DecodeCheckpoint(bytes, 4, 42), std::runtime_error);  // another problem
  EXPECT_THROW(DecodeCheckpoint(bytes.substr(0, bytes.size() - 1), 3, 42), std::runtime_error);
  EXPECT_THROW(DecodeCheckpoint(bytes + "x", 3, 42), std::runtime_error);
  EXPECT_THROW(DecodeCheckpoint("not a checkpoint", 3, 42), std::runtime_error);
  // magic 8, byte order 4, version (length 8 + text), fingerprint 8, genes 4, generation 4,
  // random state (length 8 + 0): then the population count.
  const std::size_t population_count = 8 + 4 + 8 + std::string(kVersion).size() + 8 + 4 + 4 + 8;
  std::string huge_count = bytes;
  huge_count[population_count + 5] = '\x7f';  // no giant allocation
  EXPECT_THROW(DecodeCheckpoint(huge_count, 3, 42), std::runtime_error);
}

TEST(CheckpointCodec, AnotherVersionOrOtherOptionsAreRefusedSayingWhich) {
  SearchState s;
  s.population = {{1, 0, 1}};
  s.fitness = {{}};
  s.best = {1, 0, 1};
  const std::string bytes = EncodeCheckpoint(s, 3, 42);
  try {
    DecodeCheckpoint(bytes, 3, 43);
    FAIL() << "a checkpoint of other options was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("other search options"), std::string::npos) << e.what();
  }
  std::string older = bytes;
  const std::size_t version_at = 8 + 4 + 8;
  older[version_at] = older[version_at] == '9' ? '8' : '9';  // another daemon version
  try {
    DecodeCheckpoint(older, 3, 42);
    FAIL() << "a checkpoint of another version was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("written by springfitd"), std::string::npos) << e.what();
  }
  // The fingerprint follows the resolved options: a changed operator changes it.
  SearchOptions a = StrategyDefaults(Strategy::kDefault, 20);
  SearchOptions b = a;
  EXPECT_EQ(OptionsFingerprint(a), OptionsFingerprint(b));
  b.crossover_probability = 0.8;
  EXPECT_NE(OptionsFingerprint(a), OptionsFingerprint(b));
}

}  // namespace
}  // namespace springfit::server
