// Strategy continuous (engine/identification/named_case_fit.cpp, strategy.h): fitted to the
// named load cases alone, its stops, threads and verdicts, and the settings it refuses.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "engine/api/search_options.h"
#include "engine/identification/identify.h"
#include "engine/identification/strategy.h"
#include "engine/runtime/input_error.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

// Strategy continuous fitted to the named load cases alone (search.probes none): the fit, the
// sparsity path and the cross-validation over the cases that a positions reference gets.
Scene NamedCasesOnly(Scene scene) {
  scene.search.probes = 0;
  return scene;
}

TEST(ContinuousStrategy, BeatsTheBaselineOnTheFemPlate) {
  const Problem problem = Problem::Build(NamedCasesOnly(examples::Make("fem-plate-5x5")));
  const SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  ASSERT_EQ(options.strategy, Strategy::kDefault);
  const IdentificationResult r = RunIdentification(problem, options);
  ASSERT_TRUE(r.continuous);
  ASSERT_TRUE(r.baseline);
  EXPECT_EQ(r.options.identify, Identify::kTopologyAndStiffness);
  EXPECT_EQ(r.stop, StopReason::kCompleted);
  EXPECT_FALSE(r.evaluation.mechanism);
  // The figure: E <= 0.011 with 8 nearest neighbours, against 0.82 for van Gelder.
  EXPECT_LT(std::sqrt(r.evaluation.normalized_error), 0.0115);
  EXPECT_LT(r.evaluation.normalized_error, 1e-3 * r.baseline->normalized_error);
  ASSERT_EQ(r.stiffness.size(), r.springs.size());
  for (double k : r.stiffness) EXPECT_GT(k, 0.0);
  EXPECT_TRUE(r.continuous->started_from_baseline);
  EXPECT_NEAR(r.continuous->start_normalized_error, r.baseline->normalized_error,
              1e-9 * r.baseline->normalized_error);
  ASSERT_TRUE(r.continuous->held_out_normalized_error);
  EXPECT_EQ(r.continuous->held_out_per_case.size(), problem.load_cases().size());
  // Deterministic: the same run again gives the same model.
  const IdentificationResult again = RunIdentification(problem, options);
  EXPECT_EQ(again.best, r.best);
  EXPECT_EQ(again.stiffness, r.stiffness);
}

TEST(ContinuousStrategy, ReturnsOnlyAModelTheStandardEvaluationConfirms) {
  // On the nonlinear kidney the refit of the chosen point has an equilibrium along the fit's
  // path of warm starts but none from the reference's: it is refused, the path's point taken.
  const Problem problem = Problem::Build(NamedCasesOnly(examples::Make("fem-kidney-2d-nl")));
  const IdentificationResult r = RunIdentification(
      problem, ResolveSearchOptions(problem.scene().search, problem.gene_count()));
  ASSERT_TRUE(r.continuous);
  ASSERT_TRUE(r.baseline);
  EXPECT_TRUE(r.evaluation.converged);
  EXPECT_FALSE(r.evaluation.mechanism);
  EXPECT_LT(r.evaluation.normalized_error, 0.05 * r.baseline->normalized_error);
  EXPECT_GE(r.continuous->rejected, 1);
}

TEST(ContinuousStrategy, MaxSpringsAndTargetErrorChooseThePoint) {
  Scene scene = NamedCasesOnly(examples::Make("fem-plate-5x5"));
  scene.search.max_springs = 60;
  const Problem problem = Problem::Build(scene);
  const IdentificationResult r = RunIdentification(
      problem, ResolveSearchOptions(problem.scene().search, problem.gene_count()));
  EXPECT_LE(static_cast<int>(r.springs.size()), 60);
  scene.search.max_springs.reset();
  scene.search.target_error = 0.05;
  const Problem targeted = Problem::Build(scene);
  const IdentificationResult t = RunIdentification(
      targeted, ResolveSearchOptions(targeted.scene().search, targeted.gene_count()));
  EXPECT_LE(std::sqrt(t.evaluation.normalized_error), 0.05);
  EXPECT_EQ(t.stop, StopReason::kTargetReached);
  ASSERT_TRUE(t.continuous);
  // The fewest springs within the target: every smaller point of the path misses it.
  for (const auto& p : t.continuous->path) {
    if (p.springs < t.continuous->path[t.continuous->chosen].springs) {
      EXPECT_GT(p.normalized_error, 0.05 * 0.05);
    }
  }
}

TEST(ContinuousStrategy, StoppedAfterItsFirstRowKeepsAModelBetterThanTheBaseline) {
  const Problem problem = Problem::Build(NamedCasesOnly(examples::Make("fem-kidney-2d")));
  RunContext context;
  context.on_iteration = [](const TraceRow&, const IterationState&) { return false; };
  const IdentificationResult r = RunIdentification(
      problem, ResolveSearchOptions(problem.scene().search, problem.gene_count()), context);
  EXPECT_EQ(r.stop, StopReason::kCancelled);
  ASSERT_TRUE(r.baseline);
  EXPECT_FALSE(r.evaluation.mechanism);
  EXPECT_LT(r.evaluation.normalized_error, r.baseline->normalized_error);
  EXPECT_EQ(r.trace.size(), 1u);
}

TEST(ContinuousStrategy, StoppedAtTheFitsLastRowKeepsTheFit) {
  // The fit's last row is written when the path begins: a stop there keeps the fit's model.
  const Problem problem = Problem::Build(NamedCasesOnly(examples::Make("fem-plate-5x5")));
  const SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  const IdentificationResult whole = RunIdentification(problem, options);
  ASSERT_GE(whole.trace.size(), 2u);
  const int last = whole.trace.back().generation;
  RunContext context;
  context.on_iteration = [last](const TraceRow& row, const IterationState&) {
    return row.generation < last;
  };
  const IdentificationResult r = RunIdentification(problem, options, context);
  EXPECT_EQ(r.stop, StopReason::kCancelled);
  ASSERT_TRUE(r.continuous);
  ASSERT_EQ(r.continuous->path.size(), 1u);  // the fit's point, no more
  EXPECT_FALSE(r.evaluation.mechanism);
  EXPECT_NEAR(r.evaluation.normalized_error, whole.continuous->fit_normalized_error,
              1e-6 * whole.continuous->fit_normalized_error);
}

TEST(ContinuousStrategy, SameResultWithOneOrTwoThreads) {
  // The load cases' solves run on the pool: each case has its own state.
  const Problem problem = Problem::Build(NamedCasesOnly(examples::Make("fem-plate-5x5")));
  const SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  RunContext one, two;
  two.threads = 2;
  const IdentificationResult a = RunIdentification(problem, options, one);
  const IdentificationResult b = RunIdentification(problem, options, two);
  EXPECT_EQ(a.best, b.best);
  EXPECT_EQ(a.stiffness, b.stiffness);
  EXPECT_EQ(a.evaluation.normalized_error, b.evaluation.normalized_error);
  ASSERT_EQ(a.trace.size(), b.trace.size());
  for (std::size_t i = 0; i < a.trace.size(); ++i) EXPECT_TRUE(a.trace[i].SameSearch(b.trace[i]));
}

TEST(ContinuousStrategy, SettingsThatDoNotFitTheStrategyAreRefused) {
  Scene s = examples::Make("fem-plate-5x5");
  s.search.identify = Identify::kTopology;
  EXPECT_THROW(Problem::Build(s), InputError);
  s = examples::Make("paper-iso-5x5");
  s.search.max_springs = 10;  // default is hybrid on an MSS reference
  EXPECT_THROW(Problem::Build(s), InputError);
  s.search.strategy = Strategy::kContinuous;
  EXPECT_NO_THROW(Problem::Build(s));
  s.search.max_springs = 0;
  EXPECT_THROW(Problem::Build(s), InputError);
}

// A bound on the stiffness spread is a ratio above 1, for the fit to probes alone.
TEST(ContinuousStrategy, AStiffnessSpreadBoundNeedsTheFitToProbes) {
  Scene s = examples::Make("fem-plate-5x5");
  s.search.max_spread = 100.0;
  EXPECT_NO_THROW(Problem::Build(s));
  for (double bad : {1.0, 0.5, std::numeric_limits<double>::infinity()}) {
    s.search.max_spread = bad;
    EXPECT_THROW(Problem::Build(s), InputError) << bad;
  }
  s.search.max_spread = 100.0;
  s.search.probes = 0;  // none: the named cases' fit
  EXPECT_THROW(Problem::Build(s), InputError);
  s.search.probes.reset();
  s.search.target_error = 0.05;
  EXPECT_THROW(Problem::Build(s), InputError);
  s.search.target_error.reset();
  s.search.strategy = Strategy::kHybrid;
  EXPECT_THROW(Problem::Build(s), InputError);
}

// The genetic search's settings where no genetic search runs (issue 33 item 5): refused, naming
// the setting that acts; accepted where one runs.
TEST(ContinuousStrategy, GeneticSettingsAreRefusedWhereNoGeneticSearchRuns) {
  const auto message = [](const Scene& s) -> std::string {
    try {
      Problem::Build(s);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  Scene s = examples::Make("fem-plate-5x5");  // default: continuous
  s.search.target_normalized_error = 0.01;
  std::string m = message(s);
  EXPECT_NE(m.find("search.target_normalized_error"), std::string::npos) << m;
  EXPECT_NE(m.find("--target-error"), std::string::npos) << m;
  s.search.target_normalized_error = 0.0;
  s.search.population = 20;
  m = message(s);
  EXPECT_NE(m.find("search.population"), std::string::npos) << m;
  s.search.strategy = Strategy::kPaper;
  EXPECT_EQ(message(s), "");
  s = examples::Make("paper-iso-5x5");
  s.search.strategy = Strategy::kDirect;
  s.search.stall_generations = 5;
  m = message(s);
  EXPECT_NE(m.find("search.stall_generations"), std::string::npos) << m;
  s.search.stall_generations.reset();
  s.search.target_normalized_error = 0.01;  // direct reads the target
  EXPECT_EQ(message(s), "");
  s.search.strategy = Strategy::kHybrid;
  s.search.mutation_probability = 0.1;
  EXPECT_EQ(message(s), "");
}

// A continuous run whose only model cannot carry the loads says so in its stop reason, and the
// result names the strategy that ran.
TEST(ContinuousStrategyVerdict, AMechanismIsNeverCompleted) {
  Scene s = examples::Make("paper-iso-5x5");
  s.candidates.kind = CandidateSpec::Kind::kPairs;
  s.candidates.pairs.clear();
  for (int row = 0; row < 5; ++row)  // horizontals only: nothing holds a vertical load
    for (int col = 0; col + 1 < 5; ++col)
      s.candidates.pairs.push_back({5 * row + col, 5 * row + col + 1});
  s.search.strategy = Strategy::kContinuous;
  s.search.probes = 0;
  const Problem problem(s);
  const IdentificationResult r =
      RunIdentification(problem, ResolveSearchOptions(s.search, problem.gene_count()));
  EXPECT_EQ(r.ran, Strategy::kContinuous);
  EXPECT_EQ(r.stop, StopReason::kMechanism) << r.stop_message;
  EXPECT_NE(r.stop_message.find("(the run ended: no model with an equilibrium"), std::string::npos)
      << r.stop_message;
  EXPECT_FALSE(r.usable());
}

TEST(ContinuousStrategyVerdict, TheResultNamesTheStrategyThatRan) {
  const Problem fem(examples::Make("fem-plate-5x5"));
  const IdentificationResult r =
      RunIdentification(fem, ResolveSearchOptions(fem.scene().search, fem.gene_count()));
  EXPECT_EQ(r.options.strategy, Strategy::kDefault);
  EXPECT_EQ(r.ran, Strategy::kContinuous);
}

}  // namespace
}  // namespace springfit
