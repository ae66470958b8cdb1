// The identification cost: exact zero for the reference, positive elsewhere, graded penalties.
#include "engine/problem/cost.h"

#include <cmath>

#include <gtest/gtest.h>

#include "io/example_catalog.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

TEST(Cost, ReferenceTopologyCostsExactlyZeroAndEverySingleFlipCostsMore) {
  for (const char* name : {"paper-iso-5x5", "paper-aniso-5x5", "kidney-2d", "grid3d-4x4x4"}) {
    const Problem p = Problem::Build(examples::Make(name));
    ASSERT_TRUE(p.reference_mask()) << name;
    CostFunction cost(p);
    const Genome reference = p.GenomeFromMask(*p.reference_mask());
    const Evaluation e = cost.EvaluateGenome(reference);
    EXPECT_EQ(e.cost, 0.0) << name;
    EXPECT_EQ(e.normalized_error, 0.0) << name;
    EXPECT_FALSE(e.mechanism);
    for (int g = 0; g < p.gene_count(); ++g) {
      Genome flipped = reference;
      flipped[g] ^= 1;
      const Evaluation f = cost.EvaluateGenome(flipped);
      ASSERT_TRUE(std::isfinite(f.cost)) << name << " gene " << g;
      EXPECT_GT(f.cost, 0.0) << name << " gene " << g;
    }
  }
}

TEST(Cost, HeterogeneousReferenceStiffnessReproducedExactly) {
  // stiff-2d spans stiffness 1e-4..1e4; with the reference's own stiffness the training model
  // reproduces it exactly, with the uniform training stiffness it cannot.
  const Scene scene = examples::Make("stiff-2d");
  const Problem p = Problem::Build(scene);
  CostFunction cost(p);
  ActiveSprings springs;
  for (std::size_t m = 0; m < scene.reference.springs.size(); ++m) {
    springs.index.push_back(p.CandidateIndex(scene.reference.springs[m]));
    springs.stiffness.push_back(scene.reference.stiffness[m]);
  }
  EXPECT_EQ(cost.Evaluate(springs).cost, 0.0);
  EXPECT_GT(cost.EvaluateMask(*p.reference_mask()).cost, 0.0);
}

TEST(Cost, MechanismPenaltyIsFiniteGradedAndAboveStableTopologies) {
  const Problem p = Problem::Build(examples::Make("paper-aniso-5x5"));
  CostFunction cost(p);
  const std::vector<std::uint8_t> reference = *p.reference_mask();
  // The top-left corner node 20 has only two springs in the anisotropic mesh (its cell's '/'
  // diagonal misses it): removing one leaves it hinged, a mechanism in the four cases where it
  // is free (bottom row fixed).
  std::vector<std::uint8_t> one_missing = reference;
  const int edge = p.CandidateIndex({20, 21});
  ASSERT_GE(edge, 0);
  ASSERT_TRUE(one_missing[edge]);
  one_missing[edge] = 0;
  // Removing twenty springs.
  std::vector<std::uint8_t> twenty_missing = reference;
  int removed = 0;
  for (std::size_t c = 0; c < twenty_missing.size() && removed < 20; ++c) {
    if (twenty_missing[c]) {
      twenty_missing[c] = 0;
      ++removed;
    }
  }
  const Evaluation one = cost.EvaluateMask(one_missing);
  const Evaluation twenty = cost.EvaluateMask(twenty_missing);
  const Evaluation none = cost.EvaluateMask(std::vector<std::uint8_t>(reference.size(), 0));
  const Evaluation all = cost.EvaluateMask(std::vector<std::uint8_t>(reference.size(), 1));
  EXPECT_TRUE(one.mechanism);
  EXPECT_TRUE(twenty.mechanism);
  EXPECT_FALSE(all.mechanism);
  for (const Evaluation* e : {&one, &twenty, &none}) {
    EXPECT_TRUE(std::isfinite(e->cost));
    EXPECT_GE(e->normalized_error, 2 * kPenaltyBase);
    EXPECT_GT(e->cost, all.cost);
    for (const LoadCaseEvaluation& lc : e->load_cases) EXPECT_TRUE(std::isfinite(lc.cost));
  }
  EXPECT_LT(one.cost, twenty.cost);
  EXPECT_LT(twenty.cost, none.cost);
  EXPECT_EQ(one.mechanism_modes, 4);  // one hinge mode under each of the 4 cases
  // Deterministic: the same topology, the same penalty.
  EXPECT_EQ(cost.EvaluateMask(twenty_missing).cost, twenty.cost);
}

TEST(Cost, WarmStartDoesNotChangeTheAnswer) {
  const Problem p = Problem::Build(examples::Make("kidney-2d"));
  CostFunction from_reference(p, {CostOptions::WarmStart::kReference, false, std::nullopt});
  CostFunction from_rest(p, {CostOptions::WarmStart::kRest, false, std::nullopt});
  const std::vector<std::uint8_t> all(p.candidates().size(), 1);
  const Evaluation a = from_reference.EvaluateMask(all);
  const Evaluation b = from_rest.EvaluateMask(all);
  EXPECT_NEAR(a.normalized_error, b.normalized_error, 1e-9 * a.normalized_error);
}

TEST(Cost, NormalisedErrorIsInvariantToTheSceneScale) {
  for (int dim : {2, 3}) {
    const Scene base = testing::JitteredScene(dim, dim == 2 ? 5 : 3, 0.15, 3);
    const Problem p0 = Problem::Build(base);
    std::vector<std::uint8_t> mask(p0.candidates().size(), 1);
    // Drop every third candidate that keeps the model stable, to get a nonzero error.
    CostFunction c0(p0);
    for (std::size_t c = 0; c < mask.size(); c += 3) {
      mask[c] = 0;
      if (c0.EvaluateMask(mask).mechanism) mask[c] = 1;
    }
    const Evaluation e0 = c0.EvaluateMask(mask);
    ASSERT_FALSE(e0.mechanism);
    ASSERT_GT(e0.normalized_error, 1e-6);
    for (double s : {1e-6, 1e6}) {
      const Problem ps = Problem::Build(testing::ScaledScene(base, s));
      CostFunction cs(ps);
      const Evaluation es = cs.EvaluateMask(mask);
      EXPECT_NEAR(es.normalized_error, e0.normalized_error, 1e-9 * e0.normalized_error)
          << "scale " << s;
      EXPECT_NEAR(es.cost, e0.cost * s * s, 1e-9 * e0.cost * s * s);
      for (std::size_t k = 0; k < es.load_cases.size(); ++k) {
        EXPECT_EQ(es.load_cases[k].solve.iterations, e0.load_cases[k].solve.iterations);
      }
    }
  }
}

}  // namespace
}  // namespace springfit
