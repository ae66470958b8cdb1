#include "engine/candidates.h"

#include <gtest/gtest.h>

#include "engine/examples/catalog.h"
#include "engine/input_error.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

TEST(Candidates, GridNeighbourhoodCounts) {
  // 2D n x n: 2 n (n-1) axis pairs + 2 (n-1)^2 diagonals; 5x5 gives the paper's 72.
  EXPECT_EQ(GenerateCandidates(testing::GridScene(2, 5)).size(), 72u);
  // 3D n^3 with 26 neighbours: 3 n^2 (n-1) + 6 n (n-1)^2 + 4 (n-1)^3; n = 4 gives 468.
  EXPECT_EQ(GenerateCandidates(testing::GridScene(3, 4)).size(), 468u);
  // Equal to the explicit neighbourhood, spacing inferred or given, any spacing.
  Scene s = testing::GridScene(2, 4, 0.25);
  EXPECT_EQ(GenerateCandidates(s), examples::GridNeighbourSprings({4, 4}));
  s.candidates.spacing = {0.25, 0.25};
  EXPECT_EQ(GenerateCandidates(s), examples::GridNeighbourSprings({4, 4}));
}

TEST(Candidates, GridRejectsNodesOffTheLattice) {
  Scene s = testing::GridScene(2, 3);
  s.rest[2 * 4] += 0.3;
  EXPECT_THROW(GenerateCandidates(s), InputError);
}

TEST(Candidates, NearestIsSymmetricUnion) {
  Scene s = testing::GridScene(2, 3);
  s.candidates.kind = CandidateSpec::Kind::kNearest;
  s.candidates.k = 1;
  // Each node's single nearest neighbour (ties to the lower index) joins with it.
  const std::vector<NodePair> pairs = GenerateCandidates(s);
  for (int i = 0; i < 9; ++i) {
    bool has = false;
    for (const NodePair& p : pairs) has = has || p.first == i || p.second == i;
    EXPECT_TRUE(has) << i;
  }
  s.candidates.k = 8;  // every other node of a 3x3 grid
  EXPECT_EQ(GenerateCandidates(s).size(), 36u);
}

TEST(Candidates, RadiusIncludesTheBoundary) {
  Scene s = testing::GridScene(2, 3);
  s.candidates.kind = CandidateSpec::Kind::kRadius;
  s.candidates.radius = std::sqrt(2.0);
  EXPECT_EQ(GenerateCandidates(s).size(), 20u);  // 12 axis + 8 diagonal
  s.candidates.radius = 1.0;
  EXPECT_EQ(GenerateCandidates(s).size(), 12u);
}

TEST(Candidates, PairsAreOrderedAndDeduplicated) {
  Scene s = testing::GridScene(2, 3);
  s.candidates.kind = CandidateSpec::Kind::kPairs;
  s.candidates.pairs = {{4, 1}, {0, 3}};
  const std::vector<NodePair> expected{{0, 3}, {1, 4}};
  EXPECT_EQ(GenerateCandidates(s), expected);
}

}  // namespace
}  // namespace springfit
