// The random stream and the genetic operators, against their definitions and statistics.
#include <cmath>
#include <map>
#include <set>

#include <gtest/gtest.h>

#include "engine/api/checkpoint.h"
#include "engine/api/search_options.h"
#include "engine/search/fitness_cache.h"
#include "engine/search/genetic_operators.h"
#include "engine/search/random_stream.h"

namespace springfit {
namespace {

// |observed - expected| within 5 standard deviations of a binomial count.
void ExpectBinomial(double observed, double trials, double p) {
  const double sd = std::sqrt(trials * p * (1.0 - p));
  EXPECT_NEAR(observed, trials * p, 5.0 * sd) << "p = " << p;
}

TEST(RandomStream, SameSeedSameDrawsAndSavedStateResumes) {
  RandomStream a(42), b(42), c(43);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(a.NextBits(), b.NextBits());
  EXPECT_NE(a.NextBits(), c.NextBits());
  const std::string saved = a.SaveState();
  std::vector<double> expected;
  for (int i = 0; i < 50; ++i) expected.push_back(a.Uniform());
  RandomStream resumed(7);
  resumed.RestoreState(saved);
  for (int i = 0; i < 50; ++i) EXPECT_EQ(resumed.Uniform(), expected[i]);
  EXPECT_THROW(resumed.RestoreState("not a state"), std::invalid_argument);
}

TEST(RandomStream, OwnMappingIsFixed) {
  // The first draws of seed 1 pin the mapping from bits to numbers (the engine's output is
  // fixed by the standard: mt19937_64's 10000th output from the default seed is fixed too).
  RandomStream r(5489);
  for (int i = 0; i < 9999; ++i) r.NextBits();
  EXPECT_EQ(r.NextBits(), 9981545732273789042ULL);
  RandomStream s(1);
  const std::uint64_t bits = RandomStream(1).NextBits();
  EXPECT_EQ(s.Uniform(), static_cast<double>(bits >> 11) * 0x1.0p-53);
}

TEST(RandomStream, UniformAndBelowAreInRangeAndUnbiased) {
  RandomStream r(3);
  std::vector<int> counts(7, 0);
  const int n = 70000;
  for (int i = 0; i < n; ++i) {
    const double u = r.Uniform();
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    const int b = r.Below(7);
    ASSERT_GE(b, 0);
    ASSERT_LT(b, 7);
    ++counts[b];
  }
  for (int c : counts) ExpectBinomial(c, n, 1.0 / 7.0);
  EXPECT_THROW(r.Below(std::uint64_t{0}), std::invalid_argument);
  EXPECT_FALSE(r.Bernoulli(0.0));
  EXPECT_TRUE(r.Bernoulli(1.0));
}

TEST(GeneticOperators, OnePointCrossoverSwapsTheTailsAtAPointInRange) {
  RandomStream r(11);
  const int n = 10;
  std::set<int> cuts;
  for (int t = 0; t < 2000; ++t) {
    Genome a(n, 0), b(n, 1);
    const int cut = OnePointCrossover(a, b, r);
    ASSERT_GE(cut, 1);
    ASSERT_LE(cut, n - 1);
    cuts.insert(cut);
    for (int i = 0; i < n; ++i) {
      EXPECT_EQ(a[i], i < cut ? 0 : 1);
      EXPECT_EQ(b[i], i < cut ? 1 : 0);
    }
  }
  EXPECT_EQ(cuts.size(), static_cast<std::size_t>(n - 1));  // every cut point occurs
  Genome one{1}, other{0};
  EXPECT_EQ(OnePointCrossover(one, other, r), 0);
  EXPECT_EQ(one, Genome{1});
}

TEST(GeneticOperators, UniformCrossoverSwapsHalfTheGenesAndKeepsTheMultiset) {
  RandomStream r(12);
  const int n = 20000;
  Genome a(n, 0), b(n, 1);
  UniformCrossover(a, b, r);
  int swapped = 0;
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(a[i] + b[i], 1);
    swapped += a[i];
  }
  ExpectBinomial(swapped, n, 0.5);
}

TEST(GeneticOperators, MutationRateWithinStatisticalBounds) {
  RandomStream r(13);
  for (double p : {0.001, 0.01, 0.3}) {
    Genome g(100000, 0);
    const int flips = BitFlipMutation(g, p, r);
    int ones = 0;
    for (auto gene : g) ones += gene;
    EXPECT_EQ(ones, flips);
    ExpectBinomial(flips, 100000, p);
  }
  Genome g(50, 1);
  EXPECT_EQ(BitFlipMutation(g, 0.0, r), 0);
  EXPECT_EQ(BitFlipMutation(g, 1.0, r), 50);
  EXPECT_EQ(g, Genome(50, 0));
}

TEST(GeneticOperators, RouletteSelectsInProportionToTheWeights) {
  RandomStream r(14);
  const std::vector<double> w{1.0, 2.0, 0.0, 5.0};
  std::vector<int> counts(4, 0);
  const int n = 80000;
  for (int i = 0; i < n; ++i) ++counts[RouletteSelect(w, r)];
  ExpectBinomial(counts[0], n, 1.0 / 8.0);
  ExpectBinomial(counts[1], n, 2.0 / 8.0);
  EXPECT_EQ(counts[2], 0);
  ExpectBinomial(counts[3], n, 5.0 / 8.0);
  // All weights zero: uniform.
  const std::vector<double> zero(4, 0.0);
  std::vector<int> uniform(4, 0);
  for (int i = 0; i < n; ++i) ++uniform[RouletteSelect(zero, r)];
  for (int c : uniform) ExpectBinomial(c, n, 0.25);
}

TEST(GeneticOperators, RouletteWeightsArePowersOfTheInverseError) {
  // The paper strategy's exponent 1: exactly 1 / (e + kExactNormalizedError).
  for (double e : {0.0, 1e-6, 0.3, 2e6})
    EXPECT_EQ(RouletteWeight(e, 1.0), 1.0 / (e + kExactNormalizedError));
  // Exponent p: weight ratios are error ratios to the power p, so an individual ten times
  // closer to the reference is ten, a hundred, ... times as likely to be drawn.
  EXPECT_NEAR(RouletteWeight(0.01, 2.0) / RouletteWeight(0.1, 2.0), 100.0,
              1e-6);  // the offset 1e-12 moves it by 2e-8
  EXPECT_NEAR(RouletteWeight(0.01, 0.5) / RouletteWeight(0.1, 0.5), std::sqrt(10.0), 1e-8);
  // An exact topology's weight is finite.
  EXPECT_TRUE(std::isfinite(RouletteWeight(0.0, 3.0)));
  EXPECT_GT(RouletteWeight(0.0, 3.0), RouletteWeight(1e-9, 3.0));
}

TEST(GeneticOperators, TournamentPicksTheSmallestErrorOfItsDraws) {
  RandomStream r(15);
  const std::vector<double> errors{3.0, 1.0, 2.0, 4.0};
  std::vector<int> counts(4, 0);
  const int n = 40000;
  for (int i = 0; i < n; ++i) ++counts[TournamentSelect(errors, 2, r)];
  // Size 2 with replacement: P(rank k of 4 wins) = (2(4-k)+1)/16 for k = 0..3 (best = 0).
  ExpectBinomial(counts[1], n, 7.0 / 16.0);
  ExpectBinomial(counts[2], n, 5.0 / 16.0);
  ExpectBinomial(counts[0], n, 3.0 / 16.0);
  ExpectBinomial(counts[3], n, 1.0 / 16.0);
}

// The packed form is what checkpoints and both stores keep on disk: its layout is pinned.
TEST(GenomePacking, GeneIIsBitIModulo8OfByteIOver8AndRoundTrips) {
  Genome g(11, 0);
  g[0] = g[3] = g[8] = g[10] = 1;
  const std::string packed = PackGenome(g);
  ASSERT_EQ(packed.size(), 2u);
  EXPECT_EQ(static_cast<unsigned char>(packed[0]), 0x09);  // genes 0 and 3
  EXPECT_EQ(static_cast<unsigned char>(packed[1]), 0x05);  // genes 8 and 10
  EXPECT_EQ(UnpackGenome(packed, 11), g);
  EXPECT_EQ(UnpackGenome(packed, 13), [&] {
    Genome longer = g;
    longer.resize(13, 0);
    return longer;
  }());
  EXPECT_EQ(PackGenome(Genome{}), "");
}

TEST(FitnessCache, KeysAreDistinctAndEvictionIsFirstInFirstOut) {
  EXPECT_NE(FitnessCache::Key(Genome{1, 0, 0}), FitnessCache::Key(Genome{0, 1, 0}));
  EXPECT_EQ(FitnessCache::Key(Genome(9, 1)).size(), 2u);
  FitnessCache cache(2);
  const std::string a = FitnessCache::Key({1, 0}), b = FitnessCache::Key({0, 1}),
                    c = FitnessCache::Key({1, 1});
  cache.Insert(a, Fitness{1.0, 0.1});
  cache.Insert(b, Fitness{2.0, 0.2});
  cache.Insert(a, Fitness{9.0, 0.9});  // present: ignored
  EXPECT_EQ(cache.Find(a)->cost, 1.0);
  cache.Insert(c, Fitness{3.0, 0.3});
  EXPECT_FALSE(cache.Find(a));
  ASSERT_TRUE(cache.Find(b));
  ASSERT_TRUE(cache.Find(c));
}

}  // namespace
}  // namespace springfit
