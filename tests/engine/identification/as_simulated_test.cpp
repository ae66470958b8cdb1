// The named cases as the simulator runs the model (engine/identification/as_simulated.h): with a
// linear response the fit and E are the small-load limit's; the result adds E with the spring law
// at the cases' own size, for the model and the closed-form baseline, and the verdict and the
// headline say it.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "engine/identification/as_simulated.h"
#include "engine/identification/identify.h"
#include "engine/identification/verdict.h"
#include "engine/problem/baseline_evaluation.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

// The fem-plate-5x5 scene with every named load scaled by `scale`.
Scene ScaledPlate(double scale) {
  Scene scene = examples::Make("fem-plate-5x5");
  for (LoadCase& lc : scene.load_cases) {
    for (NodalLoad& f : lc.forces) f.value *= scale;
    for (NodalLoad& u : lc.displacements) u.value *= scale;
    for (Traction& t : lc.tractions) t.value *= scale;
  }
  return scene;
}

// A result whose model is the closed-form baseline with every other spring twice as stiff (not
// the baseline itself, so that the two errors differ).
IdentificationResult ResultOfAnotherModel(const Problem& problem) {
  IdentificationResult r;
  const std::vector<double> weights = *BaselineGeneWeights(problem);
  r.best.assign(weights.size(), 0);
  int k = 0;
  for (std::size_t g = 0; g < weights.size(); ++g) {
    if (!(weights[g] > 0.0)) continue;
    r.best[g] = 1;
    r.stiffness.push_back(weights[g] * (k++ % 2 == 0 ? 2.0 : 1.0));
  }
  r.springs = problem.SpringsOfGenome(r.best);
  return r;
}

// A linear response is scale-free: the small-load E is the same at any size of the loads. The
// springs are not: at a thousandth of the loads E as simulated is the small-load E, and at 20
// times the loads it differs from it, the model's and the baseline's.
TEST(AsSimulated, TheSpringLawAtTheLoadsSizeNotTheSmallLoadLimit) {
  std::vector<double> small_load, simulated, baseline_small_load, baseline_simulated;
  for (double scale : {1e-3, 20.0}) {
    const Problem problem(ScaledPlate(scale));
    ASSERT_EQ(problem.response(), Response::kLinear);
    const IdentificationResult r = ResultOfAnotherModel(problem);
    const auto judged = NamedCasesAsSimulated(problem, r, nullptr);
    ASSERT_TRUE(judged);
    ASSERT_TRUE(judged->baseline_rms_error);
    const auto baseline = EvaluateClosedFormBaseline(problem);
    ASSERT_TRUE(baseline);
    ActiveSprings springs;
    for (std::size_t i = 0; i < r.springs.size(); ++i) {
      springs.index.push_back(problem.CandidateIndex(r.springs[i]));
      springs.stiffness.push_back(r.stiffness[i]);
    }
    small_load.push_back(std::sqrt(CostFunction(problem).Evaluate(springs).normalized_error));
    simulated.push_back(judged->rms_error);
    baseline_small_load.push_back(baseline->rms_error);
    baseline_simulated.push_back(*judged->baseline_rms_error);
  }
  EXPECT_NEAR(small_load[0], small_load[1], 1e-6 * small_load[0]);  // scale-free
  EXPECT_NEAR(simulated[0], small_load[0], 1e-2 * small_load[0]);
  EXPECT_NEAR(baseline_simulated[0], baseline_small_load[0], 1e-2 * baseline_small_load[0]);
  EXPECT_GT(std::abs(simulated[1] - small_load[1]), 0.05 * small_load[1]);
  EXPECT_GT(std::abs(baseline_simulated[1] - baseline_small_load[1]),
            0.05 * baseline_small_load[1]);
}

// A nonlinear response is judged with the spring law already: nothing is added.
TEST(AsSimulated, NothingIsAddedToANonlinearResponse) {
  const Problem problem(examples::Make("fem-kidney-2d-nl"));
  ASSERT_EQ(problem.response(), Response::kNonlinear);
  EXPECT_FALSE(NamedCasesAsSimulated(problem, ResultOfAnotherModel(problem), nullptr));
}

// A run on a linear reference carries both figures to its outcome, and the headline gives E as
// simulated first, the small-load E labelled beside it, each with the baseline's. Its beats
// meanwhile are a phase of their own, without a model's E (the strategy's state is gone).
TEST(AsSimulated, ARunSaysBothInItsHeadline) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  RunContext context;
  context.beat_seconds = 1e-9;  // a beat at every poll
  int beats = 0;
  bool without_error = true;
  context.on_beat = [&](const ProgressBeat& beat) {
    if (beat.phase == "as_simulated") {
      ++beats;
      without_error &= std::isnan(beat.best_normalized_error);
    }
    return true;
  };
  const IdentificationResult r = RunIdentification(
      problem, ResolveSearchOptions(problem.scene().search, problem.gene_count()), context);
  EXPECT_GT(beats, 0);
  EXPECT_TRUE(without_error);
  ASSERT_TRUE(r.as_simulated);
  ASSERT_TRUE(r.outcome.simulated_rms_error);
  ASSERT_TRUE(r.outcome.baseline_simulated_rms_error);
  EXPECT_EQ(*r.outcome.simulated_rms_error, r.as_simulated->rms_error);
  const std::string headline = r.outcome.Headline();
  EXPECT_NE(headline.find(" as simulated (baseline "), std::string::npos) << headline;
  EXPECT_NE(headline.find(" small-load (baseline "), std::string::npos) << headline;
  EXPECT_LT(headline.find(" as simulated"), headline.find(" small-load")) << headline;
}

}  // namespace
}  // namespace springfit
