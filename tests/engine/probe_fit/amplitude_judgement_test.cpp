// The nonlinear judgement (engine/probe_fit/amplitude_judgement.h): small loads give the
// rest-linear errors, models that fold the mesh are counted, a linear reference is judged with
// the spring law too.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <vector>

#include "engine/probe_fit/amplitude_judgement.h"
#include "engine/probe_fit/nonlinear_solves.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/probe_evaluation.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/rest_stiffness.h"
#include "engine/runtime/worker_pool.h"
#include "io/example_catalog.h"

namespace springfit::response {
namespace {

// The nonlinear judgement (amplitude_judgement.h) on the nonlinear kidney: at a thousandth of
// the named loads' size every response is its rest-linear one, so the errors are the
// certificate's rest-linear errors on the same probes; at their full size the springs and the
// neo-Hookean reference leave that limit; the same numbers on one thread or two.
TEST(AmplitudeJudgement, SmallLoadsGiveTheRestLinearErrorsAndFullOnesDiffer) {
  const Problem problem(examples::Make("fem-kidney-2d-nl"));
  ASSERT_EQ(problem.response(), Response::kNonlinear);
  const SparseMatrix k = ReferenceRestStiffness(problem);
  // Every fourth probe of the fit's bank (the certificate passes its held-out probes and named
  // cases the same way).
  const ProbeBank all = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  ProbeBank bank = all;
  bank.probes.clear();
  for (std::size_t p = 0; p < all.probes.size(); p += 4) bank.probes.push_back(all.probes[p]);
  const std::vector<double> baseline = *BaselineGeneWeights(problem);
  std::vector<double> model = baseline;  // another model: every other spring twice as stiff
  for (std::size_t g = 0; g < model.size(); g += 2) model[g] *= 2.0;
  AmplitudeOptions options;
  options.amplitudes = {1e-3, 1.0};
  options.max_probes = 1000;  // every probe of the bank
  const std::vector<AmplitudeErrors> judged = JudgeAtAmplitudes(
      problem, bank, ModelOfWeights(problem, model), ModelOfWeights(problem, baseline), options);
  ASSERT_EQ(judged.size(), 2u);

  const std::vector<bool> include(bank.probes.size(), true);
  const ErrorSummary linear_model =
      Summarize(ProbeErrorsFor(bank, SpringRestStiffness(problem, model), include));
  const ErrorSummary linear_baseline =
      Summarize(ProbeErrorsFor(bank, SpringRestStiffness(problem, baseline), include));
  const AmplitudeErrors& small = judged[0];
  EXPECT_EQ(small.reference_failed, 0);
  EXPECT_EQ(small.model.probes, linear_model.probes);
  EXPECT_NEAR(small.model.median, linear_model.median, 1e-2 * linear_model.median);
  EXPECT_NEAR(small.model.p95, linear_model.p95, 1e-2 * linear_model.p95);
  EXPECT_NEAR(small.baseline.rms, linear_baseline.rms, 1e-2 * linear_baseline.rms);
  const AmplitudeErrors& full = judged[1];
  EXPECT_GT(std::abs(full.baseline.rms - small.baseline.rms), 1e-3 * small.baseline.rms);
  EXPECT_EQ(full.model.probes + full.reference_failed, linear_model.probes);

  // At a thousandth of the loads nothing folds.
  EXPECT_EQ(small.model_inverted, 0);
  EXPECT_EQ(small.baseline_inverted, 0);

  WorkerPool pool(2);
  const std::vector<AmplitudeErrors> threaded =
      JudgeAtAmplitudes(problem, bank, ModelOfWeights(problem, model),
                        ModelOfWeights(problem, baseline), options, nullptr, &pool);
  EXPECT_EQ(threaded[1].model.rms, full.model.rms);
  EXPECT_EQ(threaded[1].baseline.median, full.baseline.median);
  EXPECT_EQ(threaded[1].model_inverted, full.model_inverted);
}

// A model that folds the mesh under a probe is counted as inverting an element: the closed-form
// baseline on the kidney at four times the named loads folds under some pushes, and a model
// twice as stiff everywhere folds under fewer.
// The judgement's solves (SpringResponse, as the tool pushes') are load steps: a probe's sizes
// solved in turn, up and back down, reach the equilibria that exact Newton reaches from rest
// at each size alone, and each size after the first, started from the last one's equilibrium
// scaled, takes fewer Newton steps than the same solver from rest (here 4 against 6 at half
// the named load, 5 against 9 at the full load).
TEST(AmplitudeJudgement, ItsSolvesAreLoadStepsThatReachTheEquilibriaFromRest) {
  const Problem problem(examples::Make("fem-kidney-2d-nl"));
  const SpringSolverInput input(problem.scene(),
                                ModelOfWeights(problem, *BaselineGeneWeights(problem)));
  const PreparedLoadCase& lc = problem.load_cases().front();
  const FreeNodes& free = problem.free_sets()[lc.free_set];
  SpringResponse steps(input, free, LoadStepSolverOptions(problem), nullptr);
  for (const double size : {0.25, 0.5, 1.0, 0.5}) {
    SCOPED_TRACE(size);
    const std::optional<Vector> u = steps.Solve(size * lc.force, size * lc.prescribed);
    SpringResponse alone(input, free, problem.solver_options(), nullptr);
    const std::optional<Vector> v = alone.Solve(size * lc.force, size * lc.prescribed);
    ASSERT_TRUE(u && v);
    EXPECT_LE((*u - *v).norm(), 1e-8 * v->norm());
    EXPECT_EQ(alone.last_summary().chord_steps, 0);
    EXPECT_GT(alone.last_summary().iterations, 1);  // nonlinear at this size
    SpringResponse from_rest(input, free, LoadStepSolverOptions(problem), nullptr);
    ASSERT_TRUE(from_rest.Solve(size * lc.force, size * lc.prescribed));
    if (size != 0.25) {
      EXPECT_LT(steps.last_summary().iterations, from_rest.last_summary().iterations);
    }
  }
}

TEST(AmplitudeJudgement, ModelsThatFoldTheMeshAreCounted) {
  const Problem problem(examples::Make("fem-kidney-2d-nl"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBank bank = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  const std::vector<double> baseline = *BaselineGeneWeights(problem);
  std::vector<double> stiffer = baseline;
  for (double& w : stiffer) w *= 2.0;
  AmplitudeOptions options;
  options.amplitudes = {4.0};
  options.max_probes = 1000;
  WorkerPool pool(2);
  const std::vector<AmplitudeErrors> judged =
      JudgeAtAmplitudes(problem, bank, ModelOfWeights(problem, stiffer),
                        ModelOfWeights(problem, baseline), options, nullptr, &pool);
  ASSERT_EQ(judged.size(), 1u);
  EXPECT_GT(judged[0].baseline_inverted, 0);
  EXPECT_LT(judged[0].model_inverted, judged[0].baseline_inverted);
}

// A linear reference is judged as the simulator runs the springs too: the reference is the
// small-load limit at every size, so at a thousandth of the loads the springs' errors are the
// certificate's rest-linear ones, and at four times the loads every difference from them is the
// springs' own (they turn and stretch), which the rest-linear certificate cannot see.
TEST(AmplitudeJudgement, ALinearReferenceIsJudgedWithTheSpringLaw) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  ASSERT_EQ(problem.response(), Response::kLinear);
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBank all = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  ProbeBank bank = all;
  bank.probes.clear();
  for (std::size_t p = 0; p < all.probes.size(); p += 6) bank.probes.push_back(all.probes[p]);
  const std::vector<double> baseline = *BaselineGeneWeights(problem);
  AmplitudeOptions options;
  options.amplitudes = {1e-3, 4.0};
  options.max_probes = 1000;
  const SpringModel model = ModelOfWeights(problem, baseline);
  const std::vector<AmplitudeErrors> judged =
      JudgeAtAmplitudes(problem, bank, model, model, options);
  ASSERT_EQ(judged.size(), 2u);
  const std::vector<bool> include(bank.probes.size(), true);
  const ErrorSummary linear =
      Summarize(ProbeErrorsFor(bank, SpringRestStiffness(problem, baseline), include));
  EXPECT_EQ(judged[0].reference_failed, 0);
  EXPECT_EQ(judged[0].model.probes, linear.probes);
  EXPECT_NEAR(judged[0].model.median, linear.median, 1e-2 * linear.median);
  EXPECT_NEAR(judged[0].model.rms, linear.rms, 1e-2 * linear.rms);
  // (A linear reference has an equilibrium at any size: none is left out.)
  EXPECT_EQ(judged[1].reference_failed, 0);
  EXPECT_GT(std::abs(judged[1].model.rms - linear.rms), 1e-2 * linear.rms);
}

}  // namespace
}  // namespace springfit::response
