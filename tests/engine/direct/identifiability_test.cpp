// The identifiability report: unseen springs, dependent groups and the suggested load cases.
#include <algorithm>

#include <gtest/gtest.h>

#include "engine/direct/direct_identification.h"
#include "engine/direct/identifiability.h"
#include "io/example_catalog.h"

namespace springfit {
namespace {

// Three separate pieces, each with its free node held by fixed nodes:
//  - nodes 0..3: node 3 hangs on three springs, so one load case (two equations at node 3)
//    cannot tell three weights apart: one dependency among (0,3), (1,3), (2,3);
//  - nodes 4..7: the same, shifted;
//  - nodes 8..10: node 10 on two springs, which one load case does determine.
// Springs between fixed nodes are candidates too: unidentifiable.
Scene ThreePieces() {
  Scene s;
  s.name = "three-pieces";
  s.dimension = 2;
  const std::vector<std::array<double, 2>> xy = {{0, 0},  {2, 0}, {1, -1}, {1, 1},  {5, 0}, {7, 0},
                                                 {6, -1}, {6, 1}, {10, 0}, {12, 0}, {11, 1}};
  s.rest.resize(static_cast<Eigen::Index>(2 * xy.size()));
  for (std::size_t i = 0; i < xy.size(); ++i) {
    s.rest[static_cast<Eigen::Index>(2 * i)] = xy[i][0];
    s.rest[static_cast<Eigen::Index>(2 * i + 1)] = xy[i][1];
  }
  s.candidates.kind = CandidateSpec::Kind::kPairs;
  s.candidates.pairs = {{0, 1}, {0, 3}, {1, 3}, {2, 3}, {4, 7}, {5, 7}, {6, 7}, {8, 10}, {9, 10}};
  s.reference.springs = {{0, 3}, {1, 3}, {2, 3}, {4, 7}, {5, 7}, {6, 7}, {8, 10}, {9, 10}};
  s.reference.stiffness = {1.0};
  LoadCase lc;
  lc.name = "pull";
  lc.fixed = {0, 1, 2, 4, 5, 6, 8, 9};
  for (const int node : {3, 7, 10}) {
    NodalLoad f;
    f.nodes = {node};
    f.value = Vector(2);
    f.value << 0.02, 0.05;
    lc.forces.push_back(f);
  }
  s.load_cases = {lc};
  return s;
}

std::vector<NodePair> Pairs(std::initializer_list<std::pair<int, int>> list) {
  std::vector<NodePair> out;
  for (const auto& [a, b] : list) out.push_back({a, b});
  return out;
}

TEST(Identifiability, FindsExactlyTheDependentGroupsOfAHandBuiltScene) {
  const Problem problem = Problem::Build(ThreePieces());
  const IdentifiabilityReport report = AnalyseIdentifiability(problem);
  EXPECT_EQ(report.unidentifiable, Pairs({{0, 1}}));
  EXPECT_TRUE(report.unseen.empty());
  ASSERT_TRUE(report.groups_analysed);
  EXPECT_EQ(report.rank, 6);  // 8 genes, 2 dependencies
  ASSERT_EQ(report.groups.size(), 2u);
  EXPECT_EQ(report.groups[0].springs, Pairs({{0, 3}, {1, 3}, {2, 3}}));
  EXPECT_EQ(report.groups[1].springs, Pairs({{4, 7}, {5, 7}, {6, 7}}));
  EXPECT_EQ(report.groups[0].dependencies, 1);

  // The suggestion works: add the load case it describes and the group is gone.
  ASSERT_TRUE(report.groups[0].suggestion);
  const LoadSuggestion& s = *report.groups[0].suggestion;
  EXPECT_EQ(s.node, 3);
  EXPECT_EQ(s.separated, 1);
  EXPECT_NE(s.text.find("node 3"), std::string::npos);
  Scene fixed = ThreePieces();
  LoadCase extra;
  extra.fixed = fixed.load_cases[static_cast<std::size_t>(s.constraints_of)].fixed;
  NodalLoad f;
  f.nodes = {s.node};
  f.value = Vector::Zero(2);
  f.value[s.axis] = 0.05;
  extra.forces = {f};
  fixed.load_cases.push_back(extra);
  const IdentifiabilityReport after = AnalyseIdentifiability(Problem::Build(fixed));
  ASSERT_EQ(after.groups.size(), 1u);
  EXPECT_EQ(after.groups[0].springs, Pairs({{4, 7}, {5, 7}, {6, 7}}));
}

TEST(Identifiability, SpringsOfAPieceNoLoadCaseLoadsAreUnseen) {
  // Add a fourth piece to the three: nodes 11, 12 fixed, node 13 on springs (11,13) and
  // (12,13), with no force on it in any load case. The reference holds those springs, but
  // nothing stretches them: no data on them at all.
  Scene s = ThreePieces();
  const Eigen::Index n = s.rest.size();
  s.rest.conservativeResize(n + 6);
  s.rest.tail(6) << 15, 0, 17, 0, 16, 1;
  s.candidates.pairs.push_back({11, 13});
  s.candidates.pairs.push_back({12, 13});
  s.reference.springs.push_back({11, 13});
  s.reference.springs.push_back({12, 13});
  for (LoadCase& lc : s.load_cases) {
    lc.fixed.push_back(11);
    lc.fixed.push_back(12);
  }
  const Problem problem = Problem::Build(s);
  ASSERT_EQ(problem.gene_count(), 10);  // both are genes: node 13 is free
  const IdentifiabilityReport report = AnalyseIdentifiability(problem);
  EXPECT_EQ(report.unseen, Pairs({{11, 13}, {12, 13}}));
  EXPECT_EQ(report.rank, 6);            // as without the piece
  ASSERT_EQ(report.groups.size(), 2u);  // the unseen springs form no group of their own

  // Strategy direct has no weight for them and says so; without them node 13 would float, so
  // they are added to carry the loads at the median identified stiffness (a stand-in: no load
  // tells their own), and listed among the springs added to carry.
  const DirectResult direct = IdentifyDirect(problem);
  ASSERT_EQ(direct.unseen.size(), 2u);
  std::vector<double> identified;
  for (int g = 0; g < problem.gene_count(); ++g)
    if (direct.genome[g] && direct.weights[g] > 0.0) identified.push_back(direct.weights[g]);
  std::sort(identified.begin(), identified.end());
  const double median = identified[identified.size() / 2];
  for (const int g : direct.unseen) {
    const NodePair pair = problem.candidates().pairs[problem.gene_candidates()[g]];
    EXPECT_EQ(pair.second, 13);
    EXPECT_EQ(direct.genome[g], 1);
    EXPECT_EQ(direct.weights[g], 0.0);
    EXPECT_NE(std::find(direct.added_to_carry.begin(), direct.added_to_carry.end(), g),
              direct.added_to_carry.end());
    const int candidate = problem.gene_candidates()[g];
    for (int m = 0; m < direct.springs.size(); ++m) {
      if (direct.springs.index[m] == candidate) {
        EXPECT_EQ(direct.springs.stiffness[m], median);
      }
    }
  }
  EXPECT_FALSE(direct.evaluation.mechanism);
}

TEST(Identifiability, TheExamplesAreFullyIdentifiable) {
  for (const char* name :
       {"paper-iso-5x5", "paper-aniso-5x5", "kidney-2d", "grid3d-4x4x4", "stiff-2d"}) {
    const Problem problem = Problem::Build(examples::Make(name));
    const IdentifiabilityReport report = AnalyseIdentifiability(problem);
    EXPECT_TRUE(report.groups_analysed) << name;
    EXPECT_TRUE(report.groups.empty()) << name;
    EXPECT_TRUE(report.unseen.empty()) << name;
    EXPECT_EQ(report.rank, problem.gene_count()) << name;
  }
}

// Issue 31: a real mesh is analysed (it was skipped beyond 600 seen genes). fem-kidney-2d-fine's
// 2,853 genes hold 12 dependencies among 386 springs (NumPy's SVD of its force balance).
TEST(Identifiability, AMeshOfThousandsOfGenesIsAnalysed) {
  const Problem problem = Problem::Build(examples::Make("fem-kidney-2d-fine"));
  const IdentifiabilityReport report = Identifiability(problem);
  ASSERT_TRUE(report.groups_analysed) << report.not_analysed;
  EXPECT_TRUE(report.not_analysed.empty());
  EXPECT_EQ(report.rank, 2841);
  int dependencies = 0;
  std::size_t springs = 0;
  for (const DependentGroup& g : report.groups) {
    dependencies += g.dependencies;
    springs += g.springs.size();
  }
  EXPECT_EQ(dependencies, 12);
  EXPECT_EQ(springs, 386u);
  EXPECT_EQ(report.rank + dependencies, problem.gene_count());

  // Beyond the bound nothing is claimed, and the report says why.
  IdentifiabilityOptions bounded;
  bounded.max_genes = 2000;
  const IdentifiabilityReport skipped = AnalyseIdentifiability(problem, bounded);
  EXPECT_FALSE(skipped.groups_analysed);
  EXPECT_TRUE(skipped.groups.empty());
  EXPECT_EQ(skipped.not_analysed, "more than 2000 seen genes");
  EXPECT_EQ(GroupsNotAnalysedText(skipped.not_analysed),
            "not analysed (more than 2000 seen genes)");
}

// Issue 47 item 7: on an FEM reference every group gets its suggested load case too (tried on
// the FEM model's small-load response, as the MSS's), and the suggestion works: with the load
// case it describes added, that many fewer dependencies are left.
TEST(Identifiability, AnFemMeshsGroupsGetSuggestionsThatSeparateThem) {
  const Scene scene = examples::Make("fem-kidney-2d-fine");
  const Problem problem = Problem::Build(scene);
  const IdentifiabilityReport report = Identifiability(problem);
  ASSERT_TRUE(report.groups_analysed) << report.not_analysed;
  ASSERT_FALSE(report.groups.empty());
  int dependencies = 0;
  for (const DependentGroup& g : report.groups) {
    dependencies += g.dependencies;
    ASSERT_TRUE(g.suggestion) << "a group of " << g.springs.size() << " springs without one";
    EXPECT_GT(g.suggestion->separated, 0);
    EXPECT_NE(g.suggestion->text.find("add a load case with a force on node "), std::string::npos)
        << g.suggestion->text;
  }
  const LoadSuggestion& s = *report.groups[0].suggestion;
  Scene more = scene;
  const LoadCase& like = scene.load_cases[static_cast<std::size_t>(s.constraints_of)];
  LoadCase extra;
  extra.name = "suggested";
  extra.fixed = like.fixed;
  extra.displacements = like.displacements;
  // A force of the size of the scene's own (its tractions' largest nodal force).
  double size = 0.0;
  for (const PreparedLoadCase& lc : problem.load_cases())
    size = std::max(size, lc.force.lpNorm<Eigen::Infinity>());
  ASSERT_GT(size, 0.0);
  NodalLoad f;
  f.nodes = {s.node};
  f.value = Vector::Zero(scene.dimension);
  f.value[s.axis] = size;
  extra.forces = {f};
  more.load_cases.push_back(extra);
  const IdentifiabilityReport after = AnalyseIdentifiability(Problem::Build(more));
  ASSERT_TRUE(after.groups_analysed) << after.not_analysed;
  int left = 0;
  for (const DependentGroup& g : after.groups) left += g.dependencies;
  EXPECT_LE(left, dependencies - s.separated);
}

// A run's stop reaches the analysis (checked after its QR and between circuits), and an
// interrupted analysis is not kept: the next call analyses again.
TEST(Identifiability, AStopReachesTheAnalysisAndAnInterruptedOneIsNotKept) {
  const Problem problem = Problem::Build(examples::Make("fem-kidney-2d-fine"));
  Interruption stop;
  stop.Request();
  EXPECT_THROW(Identifiability(problem, &stop), Interrupted);
  const IdentifiabilityReport& report = Identifiability(problem);
  EXPECT_TRUE(report.groups_analysed) << report.not_analysed;
  EXPECT_EQ(report.rank, 2841);
}

TEST(Identifiability, OneLoadCaseOnAGridLeavesGroupsWithSuggestions) {
  Scene scene = examples::Make("paper-iso-5x5");
  scene.load_cases.resize(1);  // only 'stretch +y'
  const Problem problem = Problem::Build(scene);
  const IdentifiabilityReport report = AnalyseIdentifiability(problem);
  EXPECT_EQ(report.unidentifiable.size(), 4u);  // the bottom row, fixed in the only case
  ASSERT_FALSE(report.groups.empty());
  int dependencies = 0;
  for (const DependentGroup& g : report.groups) {
    dependencies += g.dependencies;
    EXPECT_TRUE(g.suggestion) << "a group without a suggestion";
  }
  // Every seen gene is independent or in a group: rank + dependencies = seen genes.
  EXPECT_EQ(report.rank + dependencies + static_cast<int>(report.unseen.size()),
            problem.gene_count());
}

}  // namespace
}  // namespace springfit
