#include "engine/model/candidates.h"

#include <gtest/gtest.h>

#include "engine/examples/catalog.h"
#include "engine/runtime/input_error.h"
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
  // Each node's single nearest neighbour, exact ties to the lower index: 0-1, 1-0, 2-1, 3-0,
  // 4-1, 5-2, 6-3, 7-4, 8-5.
  const std::vector<NodePair> grid_expected{{0, 1}, {0, 3}, {1, 2}, {1, 4},
                                            {2, 5}, {3, 6}, {4, 7}, {5, 8}};
  EXPECT_EQ(GenerateCandidates(s), grid_expected);
  s.candidates.k = 8;  // every other node of a 3x3 grid
  EXPECT_EQ(GenerateCandidates(s).size(), 36u);

  // Nodes on a line at 0, 1, 1.5 and 10: node 3's nearest is node 2, but node 2's is node 1;
  // the union keeps (2, 3) all the same.
  Scene line;
  line.dimension = 2;
  line.rest.resize(8);
  line.rest << 0, 0, 1, 0, 1.5, 0, 10, 0;
  line.candidates.kind = CandidateSpec::Kind::kNearest;
  line.candidates.k = 1;
  const std::vector<NodePair> one{{0, 1}, {1, 2}, {2, 3}};
  EXPECT_EQ(GenerateCandidates(line), one);
  line.candidates.k = 2;  // 0: 1, 2; 1: 2, 0; 2: 1, 0; 3: 2, 1
  const std::vector<NodePair> two{{0, 1}, {0, 2}, {1, 2}, {1, 3}, {2, 3}};
  EXPECT_EQ(GenerateCandidates(line), two);
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
  // (generation alone: the scene reader refuses a duplicate pair before this)
  s.candidates.pairs = {{4, 1}, {0, 3}, {1, 4}};
  const std::vector<NodePair> expected{{0, 3}, {1, 4}};
  EXPECT_EQ(GenerateCandidates(s), expected);
}

TEST(Candidates, MeshEdgesOnceEachPlusNearest) {
  // Two triangles sharing the edge (1, 2) have five edges; k = 1 adds each node's nearest.
  Scene s;
  s.dimension = 2;
  s.rest.resize(10);
  s.rest << 0, 0, 1, 0, 0, 1, 1, 1, 5, 5;
  s.reference.kind = Reference::Kind::kFem;
  s.reference.fem.elements = {{0, 1, 2}, {1, 3, 2}};
  s.candidates.kind = CandidateSpec::Kind::kMesh;
  s.candidates.k = 0;
  const std::vector<NodePair> edges{{0, 1}, {0, 2}, {1, 2}, {1, 3}, {2, 3}};
  EXPECT_EQ(GenerateCandidates(s), edges);
  s.candidates.k = 1;  // node 4 (not in an element here) joins its nearest, node 3
  const std::vector<NodePair> with_nearest{{0, 1}, {0, 2}, {1, 2}, {1, 3}, {2, 3}, {3, 4}};
  EXPECT_EQ(GenerateCandidates(s), with_nearest);
}

}  // namespace
}  // namespace springfit
