// The one rule a probe fit chooses models by (engine/probe_fit/model_chooser.h).
#include "engine/probe_fit/model_chooser.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "engine/probe_fit/response_fit.h"

namespace springfit::response {
namespace {

ResponseFitOptions Options(int max_springs = 0) {
  ResponseFitOptions options;
  options.min_lambda = 0.1;
  options.lambda_slack = 0.1;
  options.max_springs = max_springs;
  return options;
}

TEST(ModelChooser, TheLowestChoosingErrorWinsUnlessASupportedModelIsNearlyAsGood) {
  const ModelChooser chooser(Options());
  // A soft model (lambda 0.01) slightly better than a supported one: the supported one.
  EXPECT_EQ(chooser.Best({{100, 0.20, 0.5}, {90, 0.19, 0.01}}), 0u);
  // Much better: the soft one.
  EXPECT_EQ(chooser.Best({{100, 0.20, 0.5}, {90, 0.10, 0.01}}), 1u);
  // All supported: the lowest error, the first of equals.
  EXPECT_EQ(chooser.Best({{100, 0.3, 0.5}, {90, 0.2, 0.5}, {80, 0.2, 0.5}}), 1u);
  // From an index on.
  EXPECT_EQ(chooser.Best({{100, 0.1, 0.5}, {90, 0.2, 0.5}, {80, 0.3, 0.5}}, 1), 1u);
  // No model at all: the first.
  EXPECT_EQ(chooser.Best({{0, INFINITY, 0.0}, {0, INFINITY, 0.0}}), 0u);
}

TEST(ModelChooser, ABudgetTakesTheBestModelWithinIt) {
  const std::vector<CandidateModel> candidates = {
      {120, 0.10, 0.5},     // over the budget
      {100, 0.20, 0.5},     // within
      {95, 0.15, 0.0},      // within, but a mechanism on a support
      {90, INFINITY, 0.5},  // within, no model
      {80, 0.30, 0.5},      // within
  };
  EXPECT_EQ(ModelChooser(Options(100)).BestWithinBudget(candidates), 1u);
  EXPECT_EQ(ModelChooser(Options(100)).Choose(candidates), 1u);
  EXPECT_EQ(ModelChooser(Options(85)).BestWithinBudget(candidates), 4u);
  EXPECT_FALSE(ModelChooser(Options(50)).BestWithinBudget(candidates));
  EXPECT_EQ(ModelChooser(Options(50)).Choose(candidates), 0u);  // none within: the best
  EXPECT_FALSE(ModelChooser(Options(0)).BestWithinBudget(candidates));
  EXPECT_EQ(ModelChooser(Options(0)).Choose(candidates), 0u);
}

}  // namespace
}  // namespace springfit::response
