// Problem preparation: genes, unidentifiable candidates, reference equilibria.
#include "engine/api/problem.h"

#include <gtest/gtest.h>

#include "engine/runtime/input_error.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

TEST(Problem, CandidatesBetweenAlwaysConstrainedNodesAreUnidentifiable) {
  // 3x3 grid with the bottom row fixed in every load case: the two bottom edges between fixed
  // nodes (0,1) and (1,2) are invisible to every case.
  Scene s = testing::GridScene(2, 3);
  s.load_cases.resize(4);  // keep the four bottom-fixed cases
  const Problem p = Problem::Build(s);
  ASSERT_EQ(p.unidentifiable().size(), 2u);
  EXPECT_EQ(p.candidates().pairs[p.unidentifiable()[0]], (NodePair{0, 1}));
  EXPECT_EQ(p.candidates().pairs[p.unidentifiable()[1]], (NodePair{1, 2}));
  EXPECT_EQ(p.gene_count(), p.candidates().size() - 2);
  // With the left-fixed cases too, every candidate is seen by some case.
  const Problem all = Problem::Build(testing::GridScene(2, 3));
  EXPECT_TRUE(all.unidentifiable().empty());
}

TEST(Problem, GenomeAndMaskRoundTrip) {
  const Problem p = Problem::Build(testing::GridScene(2, 4));
  Genome g(p.gene_count());
  for (int i = 0; i < p.gene_count(); ++i) g[i] = static_cast<std::uint8_t>((i * 7) % 3 == 0);
  EXPECT_EQ(p.GenomeFromMask(p.MaskFromGenome(g)), g);
}

TEST(Problem, ReferenceMechanismIsRejectedNamingTheLoadCase) {
  Scene s = testing::GridScene(2, 3);
  s.reference.springs = {{0, 1}, {1, 2}, {3, 4}};  // most nodes float
  try {
    Problem::Build(s);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "reference");
    EXPECT_NE(std::string(e.what()).find("mechanism under load_cases[0]"), std::string::npos)
        << e.what();
  }
}

TEST(Problem, PositionsReferenceMustAgreeWithPrescribedNodes) {
  Scene s = testing::GridScene(2, 3);
  const Problem mss = Problem::Build(s);
  s.reference.kind = Reference::Kind::kPositions;
  for (const PreparedLoadCase& lc : mss.load_cases())
    s.reference.positions.push_back(s.rest + lc.reference);
  const Problem positions = Problem::Build(s);
  EXPECT_DOUBLE_EQ(positions.reference_norm2(), mss.reference_norm2());
  EXPECT_FALSE(positions.reference_mask());
  s.reference.positions[2][0] += 0.01;  // node 0 is fixed in load case 2
  try {
    Problem::Build(s);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "reference.positions[2][0]");
  }
}

}  // namespace
}  // namespace springfit

namespace springfit {
namespace {

// The reference's equilibria of `mss` as a positions scene without a training stiffness.
Scene AsPositions(const Scene& mss) {
  const Problem p = Problem::Build(mss);
  Scene s = mss;
  s.reference = Reference{};
  s.reference.kind = Reference::Kind::kPositions;
  for (const PreparedLoadCase& lc : p.load_cases())
    s.reference.positions.push_back(mss.rest + lc.reference);
  s.training_stiffness.reset();
  return s;
}

TEST(Problem, APositionsReferenceTakesItsStiffnessFromItsForceBalance) {
  // Uniform stiffness 7 in the reference: the training springs get 7, not 1.
  const Scene mss = testing::GridScene(2, 5, 1.0, 7.0);
  const Problem positions = Problem::Build(AsPositions(mss));
  EXPECT_NEAR(positions.training_stiffness(), 7.0, 1e-6 * 7.0);
  // The candidates no load case sees take it too: an export gives them to a simulator, whose
  // supports may load them (they were left at 1). (The bottom-fixed cases alone leave the bottom
  // row's edges.)
  Scene bottom_fixed = mss;
  bottom_fixed.load_cases.resize(4);
  const Problem unseen = Problem::Build(AsPositions(bottom_fixed));
  ASSERT_FALSE(unseen.unidentifiable().empty());
  EXPECT_NEAR(unseen.training_stiffness(), 7.0, 1e-6 * 7.0);
  for (const double k : unseen.unidentifiable_stiffness())
    EXPECT_EQ(k, unseen.training_stiffness());
  // Scaling the loads and the stiffness together leaves the positions: the scale is the data's.
  const Problem scaled = Problem::Build(AsPositions(testing::GridScene(2, 5, 1.0, 0.02)));
  EXPECT_NEAR(scaled.training_stiffness(), 0.02, 1e-6 * 0.02);
  // A given stiffness wins.
  Scene given = AsPositions(mss);
  given.training_stiffness = 3.0;
  EXPECT_EQ(Problem::Build(given).training_stiffness(), 3.0);
}

}  // namespace
}  // namespace springfit
