// The mode lift (engine/probe_fit/mode_lift.h): the kidney's soft modes raised by stiffening
// present springs only.
#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "engine/genome/gene_weights.h"
#include "engine/probe_fit/mode_lift.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/probe_fit/probe_objective.h"
#include "engine/probe_fit/response_fit.h"
#include "engine/problem/rest_stiffness.h"
#include "engine/problem/support_system.h"
#include "tests/engine/probe_fit/probe_fit_test_support.h"

namespace springfit::response {
namespace {

// The mode lift raises every mode the kidney's plain fit (without the held modes) leaves soft to
// min_lambda by stiffening present springs only: none added, removed or softened, and few of
// them changed.
TEST(ModeLift, LiftsTheKidneysSoftModesByStiffeningPresentSpringsOnly) {
  const KidneyAtRest kidney;
  ResponseFitOptions options = kidney.options;
  // Without the held modes the fit leaves a mode at lambda 0.133: below a min_lambda of 0.15.
  options.hold.weight = 0.0;
  options.min_lambda = 0.15;
  options.lift.target = 0.18;
  options.soft_mode_rounds = 0;
  options.lift_soft_modes = false;
  const ResponseFitResult plain =
      FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  ASSERT_LT(plain.lambda_min, options.min_lambda);
  std::vector<std::pair<int, SupportSystem>> references;
  for (std::size_t s = 0; s < kidney.bank.supports.size(); ++s) {
    if (!kidney.bank.supports[s].user) continue;
    references.emplace_back(static_cast<int>(s),
                            SupportSystem(2, kidney.bank.supports[s].constrained));
    ASSERT_TRUE(references.back().second.Factorize(kidney.k));
  }
  const ModeLift lift = LiftSoftModes(kidney.problem, plain.weights, PriorScale(kidney.prior),
                                      references, options.lift);
  EXPECT_GE(lift.rounds, 1);
  EXPECT_GT(lift.modes, 0);
  int changed = 0;
  for (std::size_t g = 0; g < plain.weights.size(); ++g) {
    if (plain.weights[g] > 0.0) {
      EXPECT_GE(lift.weights[g], plain.weights[g]) << g;
      changed += lift.weights[g] > plain.weights[g] * (1.0 + 1e-3);
    } else {
      EXPECT_EQ(lift.weights[g], 0.0) << g;
    }
  }
  EXPECT_LT(changed, PresentSprings(plain.weights) / 2);
  const SparseMatrix model = SpringRestStiffness(kidney.problem, lift.weights);
  for (const auto& [s, reference] : references)
    EXPECT_GE(SmallestGeneralizedEigenvalue(model, reference), options.min_lambda) << s;
  // In the fit (step 6) the lift is one more candidate, returned when nearly as good.
  options.lift_soft_modes = true;
  const ResponseFitResult r =
      FitResponse(kidney.problem, kidney.bank, kidney.k, kidney.prior, options);
  ASSERT_EQ(r.soft_mode_rounds.size(), 2u);
  EXPECT_FALSE(r.soft_mode_rounds[0].lifted);
  EXPECT_TRUE(r.soft_mode_rounds[1].lifted);
  EXPECT_EQ(r.soft_mode_chosen, 1);
  EXPECT_EQ(r.weights, lift.weights);
  EXPECT_GE(r.lambda_min, options.min_lambda);
  EXPECT_LE(r.select_error, (1.0 + options.lambda_slack) * plain.select_error);
}

}  // namespace
}  // namespace springfit::response
