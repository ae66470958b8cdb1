// The closed-form baseline of an FEM reference (van Gelder 1998).
#include "engine/fem/closed_form_baseline.h"
#include "engine/problem/baseline_evaluation.h"

#include <gtest/gtest.h>

#include "engine/examples/simplex_mesh.h"
#include "io/example_catalog.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

Scene UnitSquare(int dimension) {
  Scene s;
  s.dimension = dimension;
  s.reference.kind = Reference::Kind::kFem;
  s.reference.fem.materials = {Material{MaterialModel::kLinear, 2.0, 0.3}};
  if (dimension == 2) {
    s.rest.resize(8);
    s.rest << 0, 0, 1, 0, 1, 1, 0, 1;
    s.reference.fem.elements = {{0, 1, 2}, {0, 2, 3}};
    s.reference.fem.thickness = 0.5;
  } else {
    const examples::SimplexMesh cube = examples::TetrahedralBlock(1, 1, 1, 1.0);
    s.rest = cube.nodes;
    s.reference.fem.elements = cube.elements;
  }
  return s;
}

TEST(ClosedFormBaseline, VanGelderStiffnessSumsOverTheElementsOfAnEdge) {
  // k_ij = sum_T E t area(T) / l^2: a side belongs to one triangle (2 x 0.5 x 0.5 / 1), the
  // diagonal to two (2 x (2 x 0.5 x 0.5) / 2).
  const fem::ClosedFormModel m = fem::VanGelderModel(UnitSquare(2));
  ASSERT_EQ(m.springs.size(), 5u);
  for (std::size_t e = 0; e < m.springs.size(); ++e) {
    const NodePair p = m.springs[e];
    const bool diagonal = p == NodePair{0, 2};
    EXPECT_DOUBLE_EQ(m.stiffness[e], 0.5)
        << p.first << "-" << p.second << (diagonal ? " (diagonal)" : "");
  }
  // 3D: the cube's main diagonal (0, 7) belongs to all six tetrahedra of volume 1/6, length^2 3.
  const Scene cube = UnitSquare(3);
  const fem::ClosedFormModel m3 = fem::VanGelderModel(cube);
  const auto it = std::find(m3.springs.begin(), m3.springs.end(), NodePair{0, 7});
  ASSERT_NE(it, m3.springs.end());
  EXPECT_DOUBLE_EQ(m3.stiffness[it - m3.springs.begin()], 6 * 2.0 * (1.0 / 6.0) / 3.0);
  EXPECT_EQ(m3.springs.size(), 19u);  // 12 sides, 6 face diagonals, 1 main diagonal
}

TEST(ClosedFormBaseline, EvaluatedOnFemReferencesOnly) {
  const Problem plate = Problem::Build(examples::Make("fem-plate-5x5"));
  const auto report = EvaluateClosedFormBaseline(plate);
  ASSERT_TRUE(report);
  EXPECT_TRUE(report->converged);
  EXPECT_EQ(report->springs, 56);  // the plate's mesh edges: 40 sides, 16 diagonals
  EXPECT_GT(report->rms_error, 0.0);
  EXPECT_DOUBLE_EQ(report->rms_error * report->rms_error, report->normalized_error);
  EXPECT_FALSE(EvaluateClosedFormBaseline(Problem::Build(examples::Make("paper-iso-5x5"))));
}

}  // namespace
}  // namespace springfit
