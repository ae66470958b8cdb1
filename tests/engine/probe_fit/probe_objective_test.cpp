// What the fits judge every iterate by (engine/probe_fit/probe_objective.h): its judgements stop
// between solves when asked.
#include <gtest/gtest.h>

#include <functional>
#include <set>
#include <utility>

#include "engine/probe_fit/probe_objective.h"
#include "engine/runtime/interruption.h"
#include "tests/engine/probe_fit/probe_fit_test_support.h"

namespace springfit::response {
namespace {

// What the fits judge every iterate by stops between solves when asked: at 10,000 nodes one
// judgement takes seconds, and a job must stop (and beat) within one.
TEST(ProbeObjective, ItsJudgementsStopBetweenSolvesWhenAsked) {
  const KidneyAtRest kidney;
  const auto& [problem, k, options, banks, prior, bank] = kidney;
  // A poll that asks for the stop at its n-th call (checked every time: period 0).
  const auto judged_until = [&](int n, const std::function<void(const ProbeObjective&)>& judge) {
    int polls = 0;
    Interruption stop([&] { return ++polls >= n; }, 0.0);
    const ProbeObjective objective(problem, bank, k, prior, options, &stop);
    bool stopped = false;
    try {
      judge(objective);
    } catch (const Interrupted&) {
      stopped = true;
    }
    return std::make_pair(stopped, polls);
  };
  const auto select = [&](const ProbeObjective& o) { o.SelectError(prior); };
  const auto lambda = [&](const ProbeObjective& o) { o.LambdaMin(prior); };
  const auto objective = [&](const ProbeObjective& o) { o.Objective(prior, 0.0); };
  for (const auto& judge : {std::function<void(const ProbeObjective&)>(select),
                            std::function<void(const ProbeObjective&)>(lambda),
                            std::function<void(const ProbeObjective&)>(objective)}) {
    const auto [finished_stopped, checks] = judged_until(1000000, judge);
    EXPECT_FALSE(finished_stopped);
    ASSERT_GE(checks, 3);  // checked along the way, not only at the start
    const auto [stopped, polls] = judged_until(checks / 2, judge);
    EXPECT_TRUE(stopped);
    EXPECT_EQ(polls, checks / 2);
  }
  // Within a support too (the fitted probes of one support are dozens of solves).
  std::set<int> fitted_supports;
  for (const Probe& p : bank.probes)
    if (p.role == ProbeRole::kFit) fitted_supports.insert(p.support);
  EXPECT_GT(judged_until(1000000, objective).second, static_cast<int>(fitted_supports.size()));
}

}  // namespace
}  // namespace springfit::response
