// The built-in examples: what the issue and the paper say they are.
#include "io/example_catalog.h"

#include <gtest/gtest.h>

#include "engine/api/problem.h"
#include "engine/examples/catalog.h"
#include "engine/problem/small_strain.h"

namespace springfit {
namespace {

TEST(Examples, PaperScenesAreThePapers) {
  const Scene iso = examples::Make("paper-iso-5x5");
  const Scene aniso = examples::Make("paper-aniso-5x5");
  EXPECT_EQ(iso.node_count(), 25);
  EXPECT_EQ(iso.reference.springs.size(), 72u);
  EXPECT_EQ(aniso.reference.springs.size(), 56u);
  ASSERT_EQ(iso.load_cases.size(), 7u);
  // 0.05 k h per loaded node; the first four cases fix the bottom row, the last three the left.
  for (const LoadCase& lc : iso.load_cases) {
    EXPECT_EQ(lc.fixed.size(), 5u);
    ASSERT_EQ(lc.forces.size(), 1u);
    EXPECT_EQ(lc.forces[0].nodes.size(), 5u);
    EXPECT_DOUBLE_EQ(lc.forces[0].value.norm(), 0.05);
  }
  EXPECT_EQ(iso.load_cases[0].fixed, (std::vector<int>{0, 1, 2, 3, 4}));
  EXPECT_EQ(iso.load_cases[4].fixed, (std::vector<int>{0, 5, 10, 15, 20}));
  // Anisotropic: no '\' diagonal (x, y+1)-(x+1, y) remains.
  for (const NodePair& p : aniso.reference.springs) EXPECT_NE(p.second - p.first, 4);
}

TEST(Examples, EveryExampleBuildsWithAConvergedReference) {
  for (const examples::ExampleInfo& info : examples::Catalog()) {
    const Scene s = examples::Make(info.name);
    const Problem p = Problem::Build(s);  // throws if the reference has no equilibrium
    EXPECT_GT(p.gene_count(), 0) << info.name;
    // An MSS reference's topology is known; an FEM reference has none to recover.
    EXPECT_EQ(p.reference_mask().has_value(), s.reference.kind == Reference::Kind::kMss)
        << info.name;
  }
  const Scene kidney = examples::Make("kidney-2d");
  EXPECT_GE(kidney.node_count(), 60);
  EXPECT_LE(kidney.node_count(), 150);
  const Scene stiff = examples::Make("stiff-2d");
  const auto [lo, hi] =
      std::minmax_element(stiff.reference.stiffness.begin(), stiff.reference.stiffness.end());
  EXPECT_NEAR(*lo, 1e-4, 1e-16);
  EXPECT_NEAR(*hi, 1e4, 1e-8);
  EXPECT_EQ(examples::Make("grid3d-4x4x4").dimension, 3);
}

TEST(Examples, FemExamplesAreWhatTheCatalogueSays) {
  const Scene plate = examples::Make("fem-plate-5x5");
  EXPECT_EQ(plate.node_count(), 25);
  EXPECT_EQ(plate.reference.kind, Reference::Kind::kFem);
  EXPECT_EQ(plate.reference.fem.elements.size(), 32u);
  EXPECT_EQ(plate.reference.fem.plane, PlaneMode::kStress);
  ASSERT_EQ(plate.load_cases.size(), 7u);
  for (const LoadCase& lc : plate.load_cases) {
    EXPECT_TRUE(lc.forces.empty());
    ASSERT_EQ(lc.tractions.size(), 1u);
    EXPECT_EQ(lc.fixed.size(), 5u);
  }
  EXPECT_EQ(plate.load_cases[0].fixed_set, "bottom");
  EXPECT_EQ(plate.load_cases[0].tractions[0].on, "top");
  EXPECT_EQ(plate.candidates.kind, CandidateSpec::Kind::kMesh);
  // A linear example within small strain: the largest displacement is 1% of the extent (4),
  // and no doubt about its strain (engine/problem/small_strain.h).
  const Problem p = Problem::Build(plate);
  double largest = 0.0;
  for (const PreparedLoadCase& lc : p.load_cases())
    largest = std::max(largest, lc.reference.cwiseAbs().maxCoeff());
  EXPECT_GT(largest, 0.01 * 4.0 * 0.7);
  EXPECT_LT(largest, 0.01 * 4.0 * 1.0 + 1e-12);
  for (const char* linear : {"fem-plate-5x5", "fem-kidney-2d", "fem-kidney-2d-fine"})
    EXPECT_FALSE(SmallStrainWarning(Problem::Build(examples::Make(linear)))) << linear;
  const Scene nl = examples::Make("fem-kidney-2d-nl");
  EXPECT_EQ(nl.reference.fem.materials[0].model, MaterialModel::kStVenantKirchhoff);
  EXPECT_EQ(examples::Make("fem-kidney-2d").reference.fem.materials[0].model,
            MaterialModel::kLinear);
  const Scene block = examples::Make("fem-block-3d");
  EXPECT_EQ(block.dimension, 3);
  EXPECT_GE(block.node_count(), 500);
  EXPECT_LE(block.node_count(), 2000);
  EXPECT_EQ(block.load_cases.size(), 9u);
}

TEST(Examples, GridSimplicesCoverTheGrid) {
  EXPECT_EQ(examples::GridSimplices({3, 3}).size(), 4u * 4u);
  EXPECT_EQ(examples::GridSimplices({3, 3, 3}).size(), 8u * 8u);
}

TEST(Examples, FoldCheckRejectsAnInvertingLoad) {
  Scene s = examples::Make("paper-aniso-5x5");
  // 0.1 k h per node: 7-19 of the 32 triangles invert at this load (docs/ARCHITECTURE.md, "Paper7
  // load cases": the examples stay at 0.05).
  for (LoadCase& lc : s.load_cases) lc.forces[0].value *= 2.0;
  EXPECT_THROW(examples::CheckFoldFree(s, examples::GridSimplices({5, 5})), std::logic_error);
}

}  // namespace
}  // namespace springfit
