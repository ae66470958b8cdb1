// The one verdict of a result (engine/identification/verdict.h, issue 33): decided from the
// model's evaluation, the certificate and the requests, the same wherever it is shown.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "engine/identification/identify.h"
#include "engine/identification/verdict.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

// A usable result of `problem`: `springs` springs, E 0.05.
IdentificationResult UsableResult(int springs) {
  IdentificationResult r;
  r.springs.assign(static_cast<std::size_t>(springs), NodePair{0, 1});
  r.evaluation.normalized_error = 0.05 * 0.05;
  return r;
}

TEST(Verdict, AUsableModelWithEveryRequestMet) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  IdentificationResult r = UsableResult(80);
  r.options.max_springs = 80;
  r.options.target_error = 0.05;
  const Outcome o = JudgeResult(problem, r);
  EXPECT_EQ(o.verdict, Verdict::kUsable);
  EXPECT_TRUE(o.unmet.empty());
  EXPECT_TRUE(o.reason.empty());
  EXPECT_EQ(o.springs, 80);
  ASSERT_TRUE(o.rms_error);
  EXPECT_NEAR(*o.rms_error, 0.05, 1e-15);
  EXPECT_EQ(o.Headline().rfind("usable: 80 springs, E 0.05", 0), 0u) << o.Headline();
}

TEST(Verdict, AnUnmetSpringBudgetOrTargetIsAnUnmetRequestNamedOnItsOwnLine) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  IdentificationResult r = UsableResult(81);
  r.options.max_springs = 80;
  Outcome o = JudgeResult(problem, r);
  EXPECT_EQ(o.verdict, Verdict::kUnmetRequest);
  ASSERT_EQ(o.unmet.size(), 1u);
  EXPECT_NE(o.unmet[0].find("spring budget not met: 81 springs, above max_springs 80"),
            std::string::npos)
      << o.unmet[0];
  r.options.max_springs = 0;
  r.options.target_error = 0.049;
  o = JudgeResult(problem, r);
  EXPECT_EQ(o.verdict, Verdict::kUnmetRequest);
  ASSERT_EQ(o.unmet.size(), 1u);
  EXPECT_NE(o.unmet[0].find("target error not met: E 0.05, above target_error 0.049"),
            std::string::npos)
      << o.unmet[0];
}

TEST(Verdict, NoAnswerIsUnusableWithItsReasonWhateverTheRequests) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  IdentificationResult mechanism = UsableResult(10);
  mechanism.evaluation.mechanism = true;
  mechanism.evaluation.converged = false;
  mechanism.evaluation.mechanism_modes = 3;
  mechanism.options.max_springs = 5;  // unmet too: unusable wins
  Outcome o = JudgeResult(problem, mechanism);
  EXPECT_EQ(o.verdict, Verdict::kUnusable);
  EXPECT_NE(o.reason.find("mechanism (3 free modes"), std::string::npos) << o.reason;
  EXPECT_FALSE(o.rms_error);

  IdentificationResult worse = UsableResult(10);
  worse.evaluation.normalized_error = 1.91 * 1.91;
  o = JudgeResult(problem, worse);
  EXPECT_EQ(o.verdict, Verdict::kUnusable);
  EXPECT_NE(o.reason.find("E 1.91"), std::string::npos) << o.reason;
  EXPECT_NE(o.reason.find("no better than the rest shape"), std::string::npos) << o.reason;

  // Good on the named cases, but some unseen load finds a mode it leaves free.
  IdentificationResult soft = UsableResult(10);
  soft.generalization.emplace();
  soft.generalization->model_held_out.median = 0.04;
  soft.generalization->model_held_out.p95 = std::numeric_limits<double>::infinity();
  o = JudgeResult(problem, soft);
  EXPECT_EQ(o.verdict, Verdict::kUnusable);
  EXPECT_NE(o.reason.find("leaves free"), std::string::npos) << o.reason;
}

TEST(Verdict, NamesRoundTrip) {
  for (Verdict v : {Verdict::kUsable, Verdict::kUnmetRequest, Verdict::kUnusable})
    EXPECT_EQ(ParseVerdict(VerdictName(v)), v);
  EXPECT_FALSE(ParseVerdict("succeeded"));
}

// The spring budget through a real run (issue 31 item 7, issue 33 item 1): the best model within
// a budget that can be met; a budget no model meets gives the unbudgeted model and says so,
// never a mechanism that meets it.
TEST(Verdict, ASpringBudgetGivesTheBestModelWithinItOrSaysItIsNotMet) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  SearchOptions options = ResolveSearchOptions(problem.scene().search, problem.gene_count());
  options.strategy = Strategy::kContinuous;
  options.max_springs = 60;
  IdentificationResult r = RunIdentification(problem, options, RunContext{});
  EXPECT_EQ(r.outcome.verdict, Verdict::kUsable) << r.outcome.Headline();
  EXPECT_LE(r.springs.size(), 60u);
  EXPECT_GE(r.springs.size(), 40u);

  options.max_springs = 1;
  r = RunIdentification(problem, options, RunContext{});
  EXPECT_EQ(r.outcome.verdict, Verdict::kUnmetRequest) << r.outcome.Headline();
  EXPECT_TRUE(r.usable());
  EXPECT_GT(r.springs.size(), 40u);
  ASSERT_EQ(r.outcome.unmet.size(), 1u);
  EXPECT_NE(r.outcome.unmet[0].find("max_springs 1"), std::string::npos);
}

}  // namespace
}  // namespace springfit
