// Stiff and extreme scenes: stiffness ratios of 1e8, large stretch and compression, tiny and
// huge length scales. Nothing may become NaN, and converged solves must balance forces.
#include <cmath>

#include <gtest/gtest.h>

#include "engine/model/equilibrium.h"
#include "engine/problem/cost.h"
#include "io/example_catalog.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

TEST(ExtremeScenes, StiffnessRatioOf1e8SolvesInForceBalance) {
  const Scene scene = examples::Make("stiff-2d");
  const Problem p = Problem::Build(scene);  // solves the 1e-4..1e4 reference
  ActiveSprings springs;
  for (std::size_t m = 0; m < scene.reference.springs.size(); ++m) {
    springs.index.push_back(p.CandidateIndex(scene.reference.springs[m]));
    springs.stiffness.push_back(scene.reference.stiffness[m]);
  }
  for (const PreparedLoadCase& lc : p.load_cases()) {
    EquilibriumSolver solver(p.candidates(), p.free_sets()[lc.free_set]);
    ASSERT_EQ(solver.RestMechanismModes(springs), 0);
    Vector u = Vector::Zero(lc.force.size());
    const EquilibriumSummary s = solver.Solve(springs, lc.force, lc.prescribed, u);
    ASSERT_TRUE(s.converged());
    // The 1e8 spread costs iterations (measured 12-17), far from the limit.
    EXPECT_LE(s.iterations, 30);
    Vector gradient;
    solver.EnergyAndGradient(springs, lc.force, u, &gradient, false, false);
    // Relative to the load, with the round-off floor the stiffest springs allow.
    const double floor = 1e-12 * 1e4 * p.candidates().MaxRestLength();
    EXPECT_LE(gradient.lpNorm<Eigen::Infinity>(),
              std::max(1e-9 * lc.force.lpNorm<Eigen::Infinity>(), floor));
  }
}

TEST(ExtremeScenes, LargeLoadsConvergeWithoutNaN) {
  // Loads 20x the paper's on the isotropic grid: springs stretch by tens of percent and some
  // compress hard; the solve may take the projected path but must converge and balance.
  const Problem p = Problem::Build(testing::GridScene(2, 5, 1.0, 1.0, 1.0));
  const ActiveSprings springs = p.SpringsFromMask(*p.reference_mask());
  int projected = 0;
  for (const PreparedLoadCase& lc : p.load_cases()) {
    EquilibriumSolver solver(p.candidates(), p.free_sets()[lc.free_set]);
    Vector u = Vector::Zero(lc.force.size());
    const EquilibriumSummary s = solver.Solve(springs, lc.force, lc.prescribed, u);
    ASSERT_TRUE(s.converged());
    ASSERT_TRUE(u.allFinite());
    projected += s.projected_steps;
  }
  EXPECT_GT(projected, 0) << "expected compression to exercise the projected Hessian";
}

TEST(ExtremeScenes, MicrometreAndKilometreScenesGiveTheSameError) {
  const Scene base = examples::Make("paper-aniso-5x5");
  const Problem p0 = Problem::Build(base);
  CostFunction c0(p0);
  const std::vector<std::uint8_t> all(p0.candidates().size(), 1);
  const Evaluation e0 = c0.EvaluateMask(all);
  for (double s : {1e-6, 1e6}) {
    const Problem ps = Problem::Build(testing::ScaledScene(base, s));
    CostFunction cs(ps);
    const Evaluation es = cs.EvaluateMask(all);
    EXPECT_NEAR(es.normalized_error, e0.normalized_error, 1e-9 * e0.normalized_error) << s;
    EXPECT_EQ(cs.EvaluateMask(*ps.reference_mask()).cost, 0.0);
  }
}

TEST(ExtremeScenes, RandomGenomesNeverYieldNaN) {
  for (const char* name : {"paper-iso-5x5", "kidney-2d"}) {
    const Problem p = Problem::Build(examples::Make(name));
    CostFunction cost(p);
    testing::TestRandom random(3);
    for (int trial = 0; trial < 200; ++trial) {
      Genome g(p.gene_count());
      const double density = random.Uniform();
      for (auto& bit : g) bit = random.Uniform() < density;
      const Evaluation e = cost.EvaluateGenome(g);
      ASSERT_TRUE(std::isfinite(e.cost)) << name << " trial " << trial;
      ASSERT_TRUE(std::isfinite(e.normalized_error));
      if (!e.mechanism && e.converged) {
        EXPECT_LE(e.normalized_error, kPenaltyBase);
      }
    }
  }
}

}  // namespace
}  // namespace springfit
