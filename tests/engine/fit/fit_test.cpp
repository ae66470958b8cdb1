// The continuous stiffness fit and the sparsity path (engine/fit/, issue 16).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include "engine/examples/catalog.h"
#include "engine/fit/sparsity_path.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/genome/gene_weights.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/cost.h"
#include "io/example_catalog.h"
#include "tests/engine/fit/fit_test_support.h"

namespace springfit {
namespace {

// An MSS reference with per-spring stiffness over 4 decades: the fit from a uniform start on the
// reference's springs finds every stiffness (the sensitivities are exact, or Gauss-Newton would
// stall short of it).
void ExpectTheFitRecoversTheStiffness(Response response) {
  const Problem problem =
      Problem::Build(WithResponse(examples::ThinnedGrid({5, 5}, 7, 4.0), response));
  const std::vector<double> truth = problem.ReferenceWeights();
  std::vector<bool> usable(truth.size());
  std::vector<double> start(truth.size(), 0.0);
  for (std::size_t g = 0; g < truth.size(); ++g) {
    usable[g] = truth[g] > 0.0;
    start[g] = usable[g] ? 1.0 : 0.0;
  }
  StiffnessFitOptions options;
  options.descent.max_steps = 500;
  options.descent.cg_iterations = 1000;
  options.descent.cg_tolerance = 1e-12;
  const StiffnessFitResult fit = FitStiffness(problem, start, FitScope{usable, {}, {}}, options);
  ASSERT_TRUE(fit.feasible);
  EXPECT_GT(fit.initial_normalized_error, 1e-3);
  EXPECT_LT(fit.normalized_error, 1e-16);
  EXPECT_TRUE(fit.converged);
  // (Counted without a step callback too.)
  EXPECT_GT(fit.accepted, 0);
  EXPECT_LE(fit.accepted, fit.iterations);
  for (std::size_t g = 0; g < truth.size(); ++g) {
    if (usable[g]) {
      EXPECT_NEAR(fit.weights[g], truth[g], 1e-5 * truth[g]) << "gene " << g;
    } else {
      EXPECT_EQ(fit.weights[g], 0.0) << "gene " << g;
    }
  }
}

TEST(StiffnessFit, RecoversPerSpringStiffnessLinear) {
  ExpectTheFitRecoversTheStiffness(Response::kLinear);
}

TEST(StiffnessFit, RecoversPerSpringStiffnessNonlinear) {
  ExpectTheFitRecoversTheStiffness(Response::kNonlinear);
}

TEST(StiffnessFit, NeverRaisesTheErrorAndKeepsTheBounds) {
  const Problem problem = Problem::Build(examples::Make("fem-plate-5x5"));
  const std::optional<std::vector<double>> start = BaselineGeneWeights(problem);
  ASSERT_TRUE(start);
  std::vector<bool> usable(start->size(), true);
  // A candidate off the mesh edges is held at 0 whatever its gradient says.
  std::size_t held = 0;
  while ((*start)[held] > 0.0) ++held;
  usable[held] = false;
  StiffnessFitOptions options;
  options.descent.max_steps = 25;
  const StiffnessFitResult fit = FitStiffness(problem, *start, FitScope{usable, {}, {}}, options);
  const BaselineReport baseline = *EvaluateClosedFormBaseline(problem);
  EXPECT_NEAR(fit.initial_normalized_error, baseline.normalized_error,
              1e-9 * baseline.normalized_error);
  EXPECT_LT(fit.normalized_error, 0.1 * fit.initial_normalized_error);
  EXPECT_EQ(fit.weights[held], 0.0);
  int entered = 0;
  for (std::size_t g = 0; g < fit.weights.size(); ++g) {
    EXPECT_GE(fit.weights[g], 0.0);
    if ((*start)[g] == 0.0 && fit.weights[g] > 0.0) ++entered;
  }
  EXPECT_GT(entered, 0) << "no candidate off the mesh edges entered by its gradient";
  // The reported error is the model's, as the cost function computes it.
  const Evaluation e = CostFunction(problem).Evaluate(problem.SpringsOfWeights(fit.weights));
  // (Both solve to the solver's tolerance, from different starts.)
  EXPECT_NEAR(e.normalized_error, fit.normalized_error, 1e-6 * fit.normalized_error);
}

TEST(StiffnessFit, ALeftOutLoadCaseIsNotFitted) {
  const Problem problem = Problem::Build(examples::Make("fem-plate-5x5"));
  const std::vector<double> start = *BaselineGeneWeights(problem);
  std::vector<bool> usable(start.size(), true);
  std::vector<bool> cases(problem.load_cases().size(), true);
  cases[0] = false;
  StiffnessFitOptions options;
  options.descent.max_steps = 10;
  const StiffnessFitResult fit = FitStiffness(problem, start, FitScope{usable, cases, {}}, options);
  CostOptions all;
  all.solve_cases_of_mechanisms = true;
  const Evaluation e = CostFunction(problem, all).Evaluate(problem.SpringsOfWeights(fit.weights));
  double cost = 0.0, norm2 = 0.0;
  for (std::size_t k = 1; k < problem.load_cases().size(); ++k) {
    cost += e.load_cases[k].cost;
    norm2 += problem.load_cases()[k].reference_norm2;
  }
  EXPECT_NEAR(fit.normalized_error, cost / norm2, 1e-6 * fit.normalized_error);
}

TEST(StiffnessFit, RegularizationPullsTowardThePriorAndReportsTheDataError) {
  const Problem problem = Problem::Build(examples::Make("fem-plate-5x5"));
  const std::vector<double> start = *BaselineGeneWeights(problem);
  const std::vector<bool> usable(start.size(), true);
  StiffnessFitOptions options;
  options.descent.max_steps = 40;
  options.saliency_probes = 0;
  // The mean square relative distance from the prior (the start), as the penalty measures it.
  const double floor = options.scale_floor * MedianPositive(start);
  const auto distance = [&](const std::vector<double>& w) {
    double sum = 0.0;
    for (std::size_t g = 0; g < w.size(); ++g)
      sum += std::pow((w[g] - start[g]) / std::max(start[g], floor), 2);
    return sum / static_cast<double>(w.size());
  };
  const StiffnessFitResult free = FitStiffness(problem, start, FitScope{usable, {}, {}}, options);
  options.regularization = 1e-2;
  const StiffnessFitResult pulled = FitStiffness(problem, start, FitScope{usable, {}, {}}, options);
  EXPECT_LT(distance(pulled.weights), 0.5 * distance(free.weights));
  EXPECT_GT(pulled.normalized_error, free.normalized_error);
  // What it minimised, E^2 + 0.01 x distance, is below the start's (distance 0 there).
  EXPECT_LT(pulled.normalized_error + 1e-2 * distance(pulled.weights),
            pulled.initial_normalized_error);
  // Its E is the data's alone, as the cost function computes it.
  const Evaluation e = CostFunction(problem).Evaluate(problem.SpringsOfWeights(pulled.weights));
  EXPECT_NEAR(e.normalized_error, pulled.normalized_error, 1e-6 * pulled.normalized_error);
  // An explicit prior is what it pulls toward. From the free fit's weights: toward the start
  // (lowering E^2 + 0.01 x distance from where it was), or kept near where it is by a prior
  // there.
  options.descent.max_steps = 5;
  const StiffnessFitResult held =
      FitStiffness(problem, free.weights, FitScope{usable, {}, free.weights}, options);
  const StiffnessFitResult back =
      FitStiffness(problem, free.weights, FitScope{usable, {}, start}, options);
  EXPECT_LT(distance(back.weights), 0.9 * distance(held.weights));
  EXPECT_LT(back.normalized_error + 1e-2 * distance(back.weights),
            free.normalized_error + 1e-2 * distance(free.weights));
}

TEST(SparsityPath, HeldOutErrorsDependOnTheModelsSpringsNotTheirFittedStiffness) {
  const Problem problem = Problem::Build(examples::Make("fem-plate-5x5"));
  const std::vector<double> start = *BaselineGeneWeights(problem);
  const std::vector<bool> usable(start.size(), true);
  StiffnessFitOptions fit_options;
  fit_options.descent.max_steps = 60;
  fit_options.saliency_probes = 0;
  const StiffnessFitResult fit =
      FitStiffness(problem, start, FitScope{usable, {}, {}}, fit_options);
  SparsityPathOptions options;
  options.held_out_iterations = 40;
  const auto fitted = HeldOutErrors(problem, fit.weights, start, options);
  // The same springs at other stiffness: the stiffness fitted with every case, which has seen
  // the case left out, must not leak into its prediction.
  std::vector<double> other = fit.weights;
  for (double& w : other) w = w > 0.0 ? 3.0 * start[0] : 0.0;
  const auto same_springs = HeldOutErrors(problem, other, start, options);
  ASSERT_TRUE(fitted && same_springs);
  ASSERT_EQ(fitted->per_case.size(), problem.load_cases().size());
  for (std::size_t k = 0; k < fitted->per_case.size(); ++k)
    EXPECT_EQ(fitted->per_case[k], same_springs->per_case[k]) << "case " << k;
  // Predicting a case is harder than fitting it: above the fit's own E on every case, far
  // above on the one stretch along x (case 4), whose kind of deformation no other case shows;
  // under the linear response the stretch +y / compression -y pair (cases 0, 1) tell the
  // same, so each predicts the other.
  EXPECT_GT(fitted->normalized_error, fit.normalized_error);
  for (std::size_t k = 0; k < fitted->per_case.size(); ++k) {
    if (k != 4) {
      EXPECT_LT(fitted->per_case[k], 0.1 * fitted->per_case[4]) << "case " << k;
    }
  }
  EXPECT_NEAR(fitted->per_case[0], fitted->per_case[1], 1e-6 * fitted->per_case[0]);
}

TEST(SparsityPath, SelectsBySizeErrorOrTolerance) {
  SparsityPath path;
  const std::vector<std::pair<int, double>> points = {
      {100, 1.0e-4}, {90, 1.08e-4}, {80, 1.2e-4}, {70, 4e-4}, {60, 1e-2}};
  for (const auto& [springs, e] : points) path.points.push_back({springs, e, {}});
  // Within 5% of the lowest E: e <= (1.05)^2 e_min = 1.1025e-4 (E within 3.9%: point 1).
  EXPECT_EQ(SelectPathPoint(path, 0, 0.0, 0.05), 1u);
  EXPECT_EQ(SelectPathPoint(path, 0, 0.0, 0.0), 0u);
  EXPECT_EQ(SelectPathPoint(path, 75, 0.0, 0.05), 3u);  // the lowest error with <= 75 springs
  EXPECT_EQ(SelectPathPoint(path, 10, 0.0, 0.05), 4u);  // none that small: the smallest
  EXPECT_EQ(SelectPathPoint(path, 0, 5e-4, 0.05), 3u);  // the fewest springs with e <= 5e-4
  EXPECT_EQ(SelectPathPoint(path, 0, 1e-6, 0.05), 0u);  // none: the lowest error
}

TEST(SparsityPath, EveryPointCarriesTheLoadsAndTheSizeFalls) {
  const Problem problem = Problem::Build(examples::Make("fem-plate-5x5"));
  const std::vector<double> start = *BaselineGeneWeights(problem);
  const std::vector<bool> usable(start.size(), true);
  SparsityPathOptions options;
  options.fit.descent.max_steps = 60;
  // Asked to go as far as the baseline's error.
  const double baseline = EvaluateClosedFormBaseline(problem)->normalized_error;
  const SparsityPath path = TraceSparsityPath(problem, start, usable, options, baseline, 0);
  ASSERT_GE(path.points.size(), 5u);
  EXPECT_FALSE(path.interrupted);
  CostFunction cost(problem);
  for (std::size_t i = 0; i < path.points.size(); ++i) {
    const PathPoint& p = path.points[i];
    const Evaluation e = cost.Evaluate(problem.SpringsOfWeights(p.weights));
    EXPECT_FALSE(e.mechanism) << "point " << i;
    EXPECT_NEAR(e.normalized_error, p.normalized_error, 1e-6 * p.normalized_error) << "point " << i;
    if (i > 0) {
      EXPECT_LT(p.springs, path.points[i - 1].springs) << "point " << i;
    }
  }
  // It runs until it passes the baseline's error, or until no spring can be removed alone
  // without leaving a model with no equilibrium (a mechanism, or one so near it that the
  // solve fails).
  const PathPoint& last = path.points.back();
  if (last.normalized_error <= baseline) {
    for (std::size_t g = 0; g < last.weights.size(); ++g) {
      if (last.weights[g] == 0.0) continue;
      std::vector<double> without = last.weights;
      without[g] = 0.0;
      const Evaluation e = cost.Evaluate(problem.SpringsOfWeights(without));
      EXPECT_TRUE(e.mechanism || !e.converged)  // no equilibrium either way
          << "the path ended at " << last.springs << " springs after " << path.points.size()
          << " points, but gene " << g << " can be removed";
    }
  }
  // Left to itself it ends at the first point whose E passes stop_error_factor times the
  // fit's.
  options.stop_error_factor = 1.03;
  const SparsityPath near = TraceSparsityPath(problem, start, usable, options, 0.0, 0);
  const double bound = 1.03 * 1.03 * near.fit.normalized_error;
  ASSERT_GE(near.points.size(), 2u);
  EXPECT_GT(near.points.back().normalized_error, bound);
  for (std::size_t i = 0; i + 1 < near.points.size(); ++i)
    EXPECT_LE(near.points[i].normalized_error, bound) << "point " << i;
}

}  // namespace
}  // namespace springfit
