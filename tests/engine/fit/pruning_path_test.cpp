// The one sparsity path (engine/fit/pruning_path.h) on a model whose removals are scripted:
// which springs leave, how many at a time, which are kept, and when a kept one is tried again.
#include "engine/fit/pruning_path.h"

#include <gtest/gtest.h>

#include <functional>
#include <set>
#include <stdexcept>
#include <vector>

namespace springfit {
namespace {

// Springs 0..n-1, least salient first by gene. `feasible(present, removed)` says whether the
// model holds without `removed`; `costly(removed)` whether its own rule refuses them.
class ScriptedModel : public PrunableModel {
 public:
  explicit ScriptedModel(int n) {
    for (int g = 0; g < n; ++g) present_.insert(g);
  }
  std::function<bool(const std::set<int>&, const std::vector<int>&)> feasible =
      [](const std::set<int>&, const std::vector<int>&) { return true; };
  std::function<bool(const std::vector<int>&)> costly = [](const std::vector<int>&) {
    return false;
  };

  int PresentSprings() const override { return static_cast<int>(present_.size()); }
  std::vector<int> BySaliency() const override { return {present_.begin(), present_.end()}; }
  Removal Remove(const std::vector<int>& genes, bool may_refuse) override {
    calls.push_back({genes, may_refuse});
    if (calls.size() > 1000) throw std::runtime_error("the path does not end");
    if (!feasible(present_, genes)) return Removal::kInfeasible;
    if (may_refuse && costly(genes)) return Removal::kTooCostly;
    for (int g : genes) present_.erase(g);
    accepted.push_back(genes);
    return Removal::kAccepted;
  }
  const std::set<int>& present() const { return present_; }

  struct Call {
    std::vector<int> genes;
    bool may_refuse;
  };
  std::vector<Call> calls;
  std::vector<std::vector<int>> accepted;

 private:
  std::set<int> present_;
};

bool Contains(const std::vector<int>& genes, int g) {
  return std::find(genes.begin(), genes.end(), g) != genes.end();
}

TEST(PruningPath, ASpringWhoseRemovalLeavesNoModelIsKeptAndTheRestGoAFractionAtATime) {
  ScriptedModel model(10);
  model.feasible = [](const std::set<int>&, const std::vector<int>& removed) {
    return !Contains(removed, 0);  // spring 0 alone holds a node
  };
  PruningOptions options;
  options.prune_fraction = 0.3;
  PruneModel(model, 0, options);
  EXPECT_EQ(model.present(), std::set<int>{0});
  // The first try takes 3 (0.3 x 10) with spring 0 among them; halved to 1 (spring 0) it
  // still fails, and spring 0 is kept.
  ASSERT_GE(model.calls.size(), 3u);
  EXPECT_EQ(model.calls[0].genes, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(model.calls[1].genes, (std::vector<int>{0}));
  EXPECT_EQ(model.calls[2].genes, (std::vector<int>{1, 2, 3}));
  for (std::size_t i = 2; i < model.calls.size(); ++i)
    EXPECT_FALSE(Contains(model.calls[i].genes, 0)) << "call " << i << " tries the kept spring";
}

TEST(PruningPath, TheModelsOwnRefusalsHalveTheRemovalAFixedNumberOfTimes) {
  for (const int max_refusals : {1, 2}) {
    SCOPED_TRACE(max_refusals);
    ScriptedModel model(8);
    model.costly = [](const std::vector<int>& removed) { return removed.size() > 1; };
    PruningOptions options;
    options.prune_fraction = 0.5;
    options.max_refusals = max_refusals;
    PruneModel(model, 7, options);  // one step: 8 springs down to at most 7 -> one removal
    ASSERT_FALSE(model.accepted.empty());
    // min_springs 7 caps the count at 1: no refusal possible.
    EXPECT_EQ(model.accepted.front().size(), 1u);
    ScriptedModel wide(8);
    wide.costly = model.costly;
    PruneModel(wide, 4, options);
    // The first step tries 4 (refused), 2 (refused once more when allowed twice), then takes
    // what the rule can no longer refuse.
    ASSERT_GE(wide.calls.size(), 2u);
    EXPECT_EQ(wide.calls[0].genes.size(), 4u);
    EXPECT_TRUE(wide.calls[0].may_refuse);
    EXPECT_EQ(wide.calls[1].genes.size(), 2u);
    EXPECT_EQ(wide.calls[1].may_refuse, max_refusals >= 2);
    EXPECT_EQ(wide.accepted.front().size(), max_refusals >= 2 ? 1u : 2u);
    EXPECT_EQ(wide.PresentSprings(), 4);
  }
}

TEST(PruningPath, AKeptSpringIsTriedAgainAfterOtherRemovalsWhenAsked) {
  for (const bool retry_kept : {false, true}) {
    SCOPED_TRACE(retry_kept);
    ScriptedModel model(6);
    // Spring 0 leaves only once spring 5 has gone (as a nonlinear model's solves depend on the
    // stiffness the refits changed).
    model.feasible = [](const std::set<int>& present, const std::vector<int>& removed) {
      return !Contains(removed, 0) || !present.count(5) || Contains(removed, 5);
    };
    PruningOptions options;
    options.prune_fraction = 0.1;  // one spring at a time
    options.retry_kept = retry_kept;
    PruneModel(model, 0, options);
    EXPECT_EQ(model.present(), retry_kept ? std::set<int>{} : std::set<int>{0});
  }
}

TEST(PruningPath, TheCountRoundsAsAskedAndStopsAtTheSizeAndWhenTold) {
  for (const bool round_up : {false, true}) {
    ScriptedModel model(10);
    PruningOptions options;
    options.prune_fraction = 0.15;
    options.round_up = round_up;
    int steps = 0;
    PruneModel(model, 3, options, [&] { return ++steps <= 2; });
    ASSERT_EQ(model.accepted.size(), 2u);
    EXPECT_EQ(model.accepted[0].size(), round_up ? 2u : 1u);  // 1.5 springs
  }
  ScriptedModel model(10);
  PruningOptions options;
  options.prune_fraction = 0.9;
  PruneModel(model, 3, options);
  EXPECT_EQ(model.PresentSprings(), 3);  // 9 asked, 7 allowed
  EXPECT_EQ(model.accepted.front().size(), 7u);
}

}  // namespace
}  // namespace springfit
