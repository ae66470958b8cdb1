// The topology search end to end: exact recovery, determinism across threads, scale and
// cache, cancellation and resumption from a snapshot.
#include <cmath>

#include <gtest/gtest.h>

#include "engine/identification/strategy.h"
#include "io/example_catalog.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

// A 3x3 grid whose reference has the sides and only the '/' diagonal of each cell: exact
// recovery must find which diagonal, which the all-candidates genome does not have.
Scene AnisotropicGrid3() {
  Scene s = testing::GridScene(2, 3);
  std::vector<NodePair> kept;
  for (const NodePair& p : s.reference.springs) {
    const double dx = s.rest[2 * p.second] - s.rest[2 * p.first];
    const double dy = s.rest[2 * p.second + 1] - s.rest[2 * p.first + 1];
    if (dx * dy < 0.0) continue;  // the '\' diagonal
    kept.push_back(p);
  }
  s.reference.springs = kept;
  return s;
}

// These tests exercise the genetic search itself: without the direct seed, which would end
// every run on these exact references in generation 0 (DefaultStrategyStartsFromTheDirectTopology).
SearchOptions Options(Strategy strategy, const Problem& p, std::uint64_t seed, int generations) {
  SearchOptions o = StrategyDefaults(strategy, p.gene_count());
  o.seed = seed;
  o.max_generations = generations;
  return o;
}

// The genetic algorithm alone (no direct seed), as the options configure it.
IdentificationResult RunGa(const Problem& p, const SearchOptions& o,
                           const RunContext& context = {}) {
  return RunIdentification(p, o, context, GeneticStrategy());
}

void ExpectSameTrace(const std::vector<TraceRow>& a, const std::vector<TraceRow>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    EXPECT_TRUE(a[i].SameSearch(b[i])) << "generation " << i;
}

TEST(Search, BothStrategiesRecoverASmallAnisotropicGridExactly) {
  const Problem p = Problem::Build(AnisotropicGrid3());
  ASSERT_TRUE(p.reference_genome());
  ASSERT_EQ(p.gene_count(), 20);
  for (Strategy strategy : {Strategy::kPaper, Strategy::kDefault}) {
    for (std::uint64_t seed : {1, 2, 3}) {
      const IdentificationResult r = RunGa(p, Options(strategy, p, seed, 1000));
      EXPECT_EQ(r.stop, StopReason::kTargetReached) << "seed " << seed;
      ASSERT_TRUE(r.exact());
      EXPECT_TRUE(*r.exact());
      EXPECT_EQ(r.best, *p.reference_genome());
      EXPECT_LE(r.evaluation.normalized_error, kExactNormalizedError);
      EXPECT_EQ(r.springs.size(), 16u);
      // The trace ends at the result and its best error never rises.
      ASSERT_FALSE(r.trace.empty());
      EXPECT_EQ(r.trace.back().generation, r.generations);
      EXPECT_EQ(r.trace.back().missing, 0);
      EXPECT_EQ(r.trace.back().extra, 0);
      for (std::size_t i = 1; i < r.trace.size(); ++i) {
        EXPECT_LE(r.trace[i].best_normalized_error, r.trace[i - 1].best_normalized_error);
        EXPECT_GE(r.trace[i].evaluations, r.trace[i - 1].evaluations);
      }
    }
  }
}

TEST(Search, DefaultStrategyStartsFromTheDirectTopology) {
  // An MSS reference: the direct topology is the reference, so the seeded GA ends at once.
  const Problem p = Problem::Build(examples::Make("kidney-2d"));
  const SearchOptions o = StrategyDefaults(Strategy::kDefault, p.gene_count());
  // default and hybrid compose direct and the GA; paper is the GA alone, unchanged.
  EXPECT_NE(dynamic_cast<HybridStrategy*>(MakeStrategy(Strategy::kDefault, p).get()), nullptr);
  EXPECT_NE(dynamic_cast<HybridStrategy*>(MakeStrategy(Strategy::kHybrid, p).get()), nullptr);
  EXPECT_NE(dynamic_cast<GeneticStrategy*>(MakeStrategy(Strategy::kPaper, p).get()), nullptr);
  EXPECT_NE(dynamic_cast<DirectStrategy*>(MakeStrategy(Strategy::kDirect, p).get()), nullptr);
  EXPECT_NE(dynamic_cast<ContinuousStrategy*>(MakeStrategy(Strategy::kContinuous, p).get()),
            nullptr);
  // On an FEM reference default is continuous.
  const Problem fem = Problem::Build(examples::Make("fem-plate-5x5"));
  EXPECT_NE(dynamic_cast<ContinuousStrategy*>(MakeStrategy(Strategy::kDefault, fem).get()),
            nullptr);
  const IdentificationResult r = RunIdentification(p, o);
  EXPECT_EQ(r.stop, StopReason::kTargetReached);
  EXPECT_EQ(r.generations, 0);
  ASSERT_TRUE(r.direct_phase);
  EXPECT_EQ(r.direct_phase->difference->hamming(), 0);
  EXPECT_EQ(r.best, *p.reference_genome());
  // The seed is the first individual: the GA evaluated it, not just the direct step.
  EXPECT_LE(r.evaluation.normalized_error, kExactNormalizedError);
}

TEST(Search, OneWrongGeneIsFarAboveTheExactThreshold) {
  const Problem p = Problem::Build(AnisotropicGrid3());
  CostFunction cost(p);
  Genome g = *p.reference_genome();
  for (int i = 0; i < p.gene_count(); ++i) {
    g[i] ^= 1;
    EXPECT_GT(cost.EvaluateGenome(g).normalized_error, 1e3 * kExactNormalizedError) << "gene " << i;
    g[i] ^= 1;
  }
}

TEST(Search, SameTraceAndResultWithOneOrTwoThreads) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  for (Strategy strategy : {Strategy::kPaper, Strategy::kDefault}) {
    const SearchOptions o = Options(strategy, p, 7, 15);
    RunContext one, two;
    one.threads = 1;
    two.threads = 2;
    const IdentificationResult a = RunGa(p, o, one);
    const IdentificationResult b = RunGa(p, o, two);
    ExpectSameTrace(a.trace, b.trace);
    EXPECT_EQ(a.best, b.best);
    EXPECT_EQ(a.evaluation.cost, b.evaluation.cost);
    EXPECT_EQ(a.counters, b.counters);
  }
}

TEST(Search, ScalingTheSceneLeavesTheSearchUnchanged) {
  const Scene base = examples::Make("paper-aniso-5x5");
  const Problem p1 = Problem::Build(base);
  const Problem p2 = Problem::Build(testing::ScaledScene(base, 1e3));
  for (Strategy strategy : {Strategy::kPaper, Strategy::kDefault}) {
    const IdentificationResult a = RunGa(p1, Options(strategy, p1, 5, 8));
    const IdentificationResult b = RunGa(p2, Options(strategy, p2, 5, 8));
    ASSERT_GT(a.trace.size(), 2u);
    ASSERT_EQ(a.trace.size(), b.trace.size());
    for (std::size_t i = 0; i < a.trace.size(); ++i) {
      EXPECT_EQ(a.trace[i].evaluations, b.trace[i].evaluations);
      EXPECT_EQ(a.trace[i].cache_hits, b.trace[i].cache_hits);
      EXPECT_EQ(a.trace[i].missing, b.trace[i].missing);
      EXPECT_EQ(a.trace[i].extra, b.trace[i].extra);
      const double ea = a.trace[i].best_normalized_error, eb = b.trace[i].best_normalized_error;
      EXPECT_LE(std::abs(ea - eb), 1e-8 * std::max(ea, 1e-12)) << "generation " << i;
      // The cost carries the unit: length^2.
      EXPECT_LE(std::abs(b.trace[i].best_cost - 1e6 * a.trace[i].best_cost),
                1e-8 * 1e6 * a.trace[i].best_cost + 1e-20);
    }
    EXPECT_EQ(a.best, b.best);
  }
}

TEST(Search, TheCacheNeverChangesResults) {
  const Problem p = Problem::Build(examples::Make("paper-iso-5x5"));
  for (Strategy strategy : {Strategy::kPaper, Strategy::kDefault}) {
    const SearchOptions o = Options(strategy, p, 3, 25);
    RunContext cached, uncached;
    uncached.use_cache = false;
    const IdentificationResult a = RunGa(p, o, cached);
    const IdentificationResult b = RunGa(p, o, uncached);
    ASSERT_EQ(a.trace.size(), b.trace.size());
    for (std::size_t i = 0; i < a.trace.size(); ++i) {
      EXPECT_EQ(a.trace[i].evaluations, b.trace[i].evaluations);
      EXPECT_EQ(a.trace[i].best_cost, b.trace[i].best_cost);
      EXPECT_EQ(a.trace[i].mean_cost, b.trace[i].mean_cost);
    }
    EXPECT_EQ(a.best, b.best);
    EXPECT_EQ(b.counters.cache_hits, 0);
    if (strategy == Strategy::kPaper) {
      EXPECT_GT(a.counters.cache_hits, 0);
    }
  }
}

TEST(Search, RouletteExponentChangesSelectionAndIsBounded) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  SearchOptions o = Options(Strategy::kPaper, p, 3, 20);
  o.stop_at_target = false;
  const IdentificationResult inverse = RunGa(p, o);
  o.roulette_exponent = 4.0;
  const IdentificationResult steep = RunGa(p, o);
  // The initial population is the same draw; what the roulette breeds from it is not.
  ASSERT_EQ(inverse.trace.size(), steep.trace.size());
  EXPECT_TRUE(inverse.trace.front().SameSearch(steep.trace.front()));
  bool differ = false;
  for (std::size_t g = 1; g < inverse.trace.size(); ++g)
    differ = differ || !inverse.trace[g].SameSearch(steep.trace[g]);
  EXPECT_TRUE(differ);
  for (double bad :
       {0.0, -1.0, std::nan(""), static_cast<double>(INFINITY), kMaxRouletteExponent * 1.1}) {
    o.roulette_exponent = bad;
    EXPECT_THROW(RunGa(p, o), std::invalid_argument) << "roulette_exponent " << bad;
  }
}

TEST(Search, BeatsReportInsideAGenerationAndCanStopIt) {
  // The memetic GA's generation 0 runs a local search of many batches: with a beat interval
  // of 0 every batch reports, before the first iteration ends.
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  const SearchOptions o = Options(Strategy::kDefault, p, 3, 5);
  int beats = 0, beats_before_first_row = -1;
  std::int64_t last_evaluations = -1;
  RunContext watched;
  watched.beat_seconds = 0.0;
  watched.on_beat = [&](const ProgressBeat& beat) {
    ++beats;
    EXPECT_GE(beat.evaluations, last_evaluations);  // progress only grows
    last_evaluations = beat.evaluations;
    return true;
  };
  watched.on_iteration = [&](const TraceRow&, const IterationState&) {
    if (beats_before_first_row < 0) beats_before_first_row = beats;
    return true;
  };
  const IdentificationResult seen = RunGa(p, o, watched);
  EXPECT_GT(beats_before_first_row, 0);
  // Watching changes nothing: the same trace and result as a run without beats.
  const IdentificationResult plain = RunGa(p, o);
  ExpectSameTrace(plain.trace, seen.trace);
  EXPECT_EQ(plain.best, seen.best);
  // Refusing the first beat abandons generation 0 at once: cancelled, far fewer evaluations.
  RunContext stopped;
  stopped.beat_seconds = 0.0;
  stopped.on_beat = [](const ProgressBeat&) { return false; };
  bool snapshot_offered = false;
  stopped.on_iteration = [&](const TraceRow&, const IterationState& state) {
    snapshot_offered = snapshot_offered || static_cast<bool>(state.snapshot);
    return true;
  };
  const IdentificationResult r = RunGa(p, o, stopped);
  EXPECT_EQ(r.stop, StopReason::kCancelled);
  EXPECT_EQ(r.generations, 0);
  EXPECT_LT(r.counters.evaluations, plain.trace.front().evaluations);
  EXPECT_FALSE(snapshot_offered);  // a step abandoned midway is no state to resume from
}

TEST(Search, StallAndTimeLimitStopTheRun) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  SearchOptions o = Options(Strategy::kPaper, p, 2, 1000);
  o.stall_generations = 4;
  const IdentificationResult stalled = RunGa(p, o);
  if (stalled.stop != StopReason::kTargetReached) {
    // A best that is no answer is said first; the stall is still in the message.
    EXPECT_EQ(stalled.stop,
              stalled.evaluation.mechanism ? StopReason::kMechanism : StopReason::kStalled);
    EXPECT_EQ(stalled.generations, stalled.best_generation + 4);
    EXPECT_NE(stalled.stop_message.find("no improvement for 4 generations"), std::string::npos)
        << stalled.stop_message;
  }
  o.stall_generations = 0;
  o.max_seconds = 1e-9;  // over before the first generation ends
  const IdentificationResult timed = RunGa(p, o);
  EXPECT_EQ(timed.stop, StopReason::kTimeLimit);
  EXPECT_EQ(timed.generations, 0);
  // default and hybrid stop after 200 stalled generations; paper never does.
  EXPECT_EQ(StrategyDefaults(Strategy::kDefault, 10).stall_generations, 200);
  EXPECT_EQ(StrategyDefaults(Strategy::kPaper, 10).stall_generations, 0);
}

TEST(Search, CancellationReturnsTheBestSoFar) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  RunContext run;
  run.on_iteration = [](const TraceRow& row, const IterationState&) { return row.generation < 3; };
  const IdentificationResult r = RunGa(p, Options(Strategy::kPaper, p, 1, 1000), run);
  EXPECT_EQ(r.stop, StopReason::kCancelled);
  EXPECT_EQ(r.generations, 3);
  ASSERT_EQ(r.trace.size(), 4u);
  EXPECT_EQ(r.evaluation.normalized_error, r.trace.back().best_normalized_error);
  EXPECT_EQ(r.difference->missing.size(), static_cast<std::size_t>(r.trace.back().missing));
}

TEST(Search, ResumingFromASnapshotEndsExactlyLikeAnUninterruptedRun) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  for (Strategy strategy : {Strategy::kPaper, Strategy::kDefault}) {
    SearchOptions o = Options(strategy, p, 9, 30);
    o.stop_at_target = false;  // (the direct phase may recover it at once)
    // Default runs as its strategy resolves (hybrid here: the direct phase seeds the GA).
    const auto run = [&](const RunContext& context) {
      return strategy == Strategy::kDefault ? RunIdentification(p, o, context)
                                            : RunGa(p, o, context);
    };
    const IdentificationResult whole = run({});
    ASSERT_GE(whole.generations, 2);
    const int stop_at = whole.generations / 2;

    std::optional<SearchState> snapshot;
    RunContext first;
    first.on_iteration = [&](const TraceRow& row, const IterationState& state) {
      if (row.generation < stop_at) return true;
      snapshot = state.snapshot();
      return false;
    };
    const IdentificationResult part = run(first);
    ASSERT_TRUE(snapshot);
    RunContext second;
    second.resume_from = snapshot;
    second.trace = part.trace;
    const IdentificationResult resumed = run(second);
    // The snapshot has no fitness cache: only cache hits may differ.
    ASSERT_EQ(whole.trace.size(), resumed.trace.size());
    for (std::size_t i = 0; i < whole.trace.size(); ++i)
      EXPECT_TRUE(whole.trace[i].SameSearchButCacheHits(resumed.trace[i])) << "generation " << i;
    EXPECT_EQ(whole.best, resumed.best);
    EXPECT_EQ(whole.counters.evaluations, resumed.counters.evaluations);
    EXPECT_EQ(whole.stop, resumed.stop);
    // The seeding direct phase (default = hybrid here) is reported alike, from the snapshot.
    ASSERT_EQ(whole.direct_phase.has_value(), strategy == Strategy::kDefault);
    ASSERT_EQ(resumed.direct_phase.has_value(), whole.direct_phase.has_value());
    if (!whole.direct_phase) continue;
    EXPECT_EQ(resumed.direct_phase->normalized_error, whole.direct_phase->normalized_error);
    EXPECT_EQ(resumed.direct_phase->seconds, part.direct_phase->seconds);  // the snapshot's run
    ASSERT_TRUE(resumed.direct_phase->difference && whole.direct_phase->difference);
    EXPECT_EQ(resumed.direct_phase->difference->missing, whole.direct_phase->difference->missing);
    EXPECT_EQ(resumed.direct_phase->difference->extra, whole.direct_phase->difference->extra);
  }
}

TEST(Search, SettingsResolveOverTheStrategyDefaults) {
  SearchSettings st;
  st.strategy = Strategy::kPaper;
  SearchOptions o = ResolveSearchOptions(st, 72);
  EXPECT_EQ(o.population, 20);
  EXPECT_EQ(o.crossover_probability, 0.3);
  EXPECT_EQ(o.mutation_probability, 0.01);
  EXPECT_EQ(o.selection, SearchOptions::Selection::kRoulette);
  EXPECT_EQ(o.crossover, SearchOptions::Crossover::kOnePoint);
  EXPECT_EQ(o.elites, 0);
  EXPECT_FALSE(o.local_search);
  st.population = 50;
  st.mutation_probability = 0.2;
  st.seed = 99;
  o = ResolveSearchOptions(st, 72);
  EXPECT_EQ(o.population, 50);
  EXPECT_EQ(o.mutation_probability, 0.2);
  EXPECT_EQ(o.seed, 99u);
  st = SearchSettings{};
  o = ResolveSearchOptions(st, 72);
  EXPECT_EQ(o.strategy, Strategy::kDefault);
  EXPECT_TRUE(o.local_search);
}

}  // namespace
}  // namespace springfit
