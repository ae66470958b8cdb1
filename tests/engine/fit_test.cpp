// The linear response, the continuous stiffness fit, the sparsity path and strategy continuous
// (engine/fit/, issue 16).
#include <gtest/gtest.h>

#include <cmath>

#include "engine/fit/sparsity_path.h"
#include "engine/fit/stiffness_fit.h"
#include "engine/identification/identify.h"
#include "engine/identification/strategy.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/cost.h"
#include "engine/problem/force_balance.h"
#include "engine/runtime/input_error.h"
#include "io/example_catalog.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

Scene WithResponse(Scene s, Response response) {
  s.search.response = response;
  return s;
}

// The reference's springs of an MSS scene, over its own geometry.
ActiveSprings ReferenceSprings(const Scene& s) {
  ActiveSprings springs;
  for (int m = 0; m < static_cast<int>(s.reference.springs.size()); ++m) {
    springs.index.push_back(m);
    springs.stiffness.push_back(s.reference.stiffness.size() == 1 ? s.reference.stiffness[0]
                                                                  : s.reference.stiffness[m]);
  }
  return springs;
}

TEST(Response, DefaultsToLinearForALinearFemReferenceOnly) {
  EXPECT_EQ(ResolveResponse(examples::Make("fem-plate-5x5")), Response::kLinear);
  EXPECT_EQ(ResolveResponse(examples::Make("fem-kidney-2d-nl")), Response::kNonlinear);
  EXPECT_EQ(ResolveResponse(examples::Make("paper-iso-5x5")), Response::kNonlinear);
  EXPECT_EQ(ResolveResponse(WithResponse(examples::Make("fem-plate-5x5"), Response::kNonlinear)),
            Response::kNonlinear);
  const Problem p =
      Problem::Build(WithResponse(examples::Make("paper-iso-5x5"), Response::kLinear));
  EXPECT_EQ(p.response(), Response::kLinear);
  EXPECT_EQ(p.solver_options().response, Response::kLinear);
}

TEST(Response, TheLinearSolveIsTheRestStiffnessSolve) {
  // u = K^-1 f with K = sum k n0 n0^T, assembled here by hand and solved densely.
  const Scene scene = examples::ThinnedGrid({4, 4}, 5, 2.0);
  const int d = scene.dimension, n = scene.node_count();
  const SpringGeometry geometry(d, scene.rest, scene.reference.springs);
  const ActiveSprings springs = ReferenceSprings(scene);
  const Problem problem = Problem::Build(WithResponse(scene, Response::kLinear));
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const PreparedLoadCase& lc = problem.load_cases()[k];
    const FreeNodes& free = problem.free_sets()[lc.free_set];
    Matrix K = Matrix::Zero(d * n, d * n);
    for (int m = 0; m < geometry.size(); ++m) {
      const Vector n0 = geometry.rest_separation.segment(d * m, d) / geometry.rest_length[m];
      const Matrix block = springs.stiffness[m] * n0 * n0.transpose();
      const int i = geometry.pairs[m].first, j = geometry.pairs[m].second;
      K.block(d * i, d * i, d, d) += block;
      K.block(d * j, d * j, d, d) += block;
      K.block(d * i, d * j, d, d) -= block;
      K.block(d * j, d * i, d, d) -= block;
    }
    std::vector<int> dofs;
    for (int i = 0; i < n; ++i) {
      if (free.free_index[i] >= 0)
        for (int a = 0; a < d; ++a) dofs.push_back(d * i + a);
    }
    const Vector rhs = lc.force - K * lc.prescribed;  // prescribed is zero on free nodes
    Matrix Kff(dofs.size(), dofs.size());
    Vector fff(dofs.size());
    for (std::size_t r = 0; r < dofs.size(); ++r) {
      fff[r] = rhs[dofs[r]];
      for (std::size_t c = 0; c < dofs.size(); ++c) Kff(r, c) = K(dofs[r], dofs[c]);
    }
    const Vector expected = Kff.ldlt().solve(fff);
    for (std::size_t r = 0; r < dofs.size(); ++r)
      EXPECT_NEAR(lc.reference[dofs[r]], expected[r], 1e-9 * expected.lpNorm<Eigen::Infinity>())
          << "load case " << k << ", dof " << dofs[r];
  }
}

TEST(Response, LinearDisplacementsScaleWithTheLoadNonlinearOnesDoNot) {
  const auto displacement = [](Response response, double factor) {
    Scene s = WithResponse(examples::Make("paper-iso-5x5"), response);
    for (LoadCase& lc : s.load_cases) {
      for (NodalLoad& f : lc.forces) f.value *= factor;
    }
    return Problem::Build(std::move(s)).load_cases()[0].reference;
  };
  const Vector lin1 = displacement(Response::kLinear, 1.0);
  const Vector lin4 = displacement(Response::kLinear, 4.0);
  EXPECT_LT((lin4 - 4.0 * lin1).norm(), 1e-10 * lin4.norm());
  const Vector nl1 = displacement(Response::kNonlinear, 1.0);
  const Vector nl4 = displacement(Response::kNonlinear, 4.0);
  EXPECT_GT((nl4 - 4.0 * nl1).norm(), 1e-3 * nl4.norm());
}

TEST(Response, TheForceBalanceHoldsAtTheLinearReferenceStiffness) {
  // The linearised spring's force per unit stiffness, at the linear equilibria: A w = b exactly.
  const Problem problem =
      Problem::Build(WithResponse(examples::ThinnedGrid({4, 4}, 3, 2.0), Response::kLinear));
  const ForceBalance fb = AssembleForceBalance(problem);
  const std::vector<double> truth = problem.ReferenceWeights();
  const Vector w = Eigen::Map<const Vector>(truth.data(), static_cast<Eigen::Index>(truth.size()));
  EXPECT_LT((fb.a * w - fb.b).norm(), 1e-10 * fb.b.norm());
}

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
  options.max_iterations = 500;
  options.max_cg_iterations = 1000;
  options.cg_tolerance = 1e-12;
  const StiffnessFitResult fit = FitStiffness(problem, start, FitScope{usable, {}, {}}, options);
  ASSERT_TRUE(fit.feasible);
  EXPECT_GT(fit.initial_normalized_error, 1e-3);
  EXPECT_LT(fit.normalized_error, 1e-16);
  EXPECT_TRUE(fit.converged);
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
  options.max_iterations = 25;
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
  options.max_iterations = 10;
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
  options.max_iterations = 40;
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
  options.max_iterations = 5;
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
  fit_options.max_iterations = 60;
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
  options.fit.max_iterations = 60;
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

}  // namespace
}  // namespace springfit
