// The k-d tree's answers against comparing every pair (the code it replaced), on layouts with
// exact ties (grids), random clouds and nodes on one line; the candidate estimate a service
// checks before generating candidates; the memetic swap partners against every pair.
#include "engine/model/point_index.h"

#include <algorithm>
#include <random>
#include <utility>

#include <gtest/gtest.h>

#include "engine/api/problem.h"
#include "engine/api/scene.h"
#include "engine/model/candidates.h"
#include "engine/runtime/input_error.h"
#include "engine/search/genetic_search.h"
#include "io/example_catalog.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

double Dist(const Vector& p, int d, int i, int j) {
  return (p.segment(d * i, d) - p.segment(d * j, d)).norm();
}

std::vector<int> BruteNearest(const Vector& p, int d, int i, int k) {
  std::vector<std::pair<double, int>> all;
  for (int j = 0; j < p.size() / d; ++j)
    if (j != i) all.emplace_back(Dist(p, d, i, j), j);
  std::sort(all.begin(), all.end());
  std::vector<int> out;
  for (int r = 0; r < k && r < static_cast<int>(all.size()); ++r) out.push_back(all[r].second);
  return out;
}

std::vector<int> BruteWithin(const Vector& p, int d, int i, double radius) {
  std::vector<int> out;
  for (int j = 0; j < p.size() / d; ++j)
    if (Dist(p, d, i, j) <= radius) out.push_back(j);
  return out;
}

// Point sets whose answers are full of exact ties, and ones with none.
std::vector<std::pair<Vector, int>> Layouts() {
  std::vector<std::pair<Vector, int>> out;
  out.emplace_back(testing::GridScene(2, 9).rest, 2);
  out.emplace_back(testing::GridScene(3, 5).rest, 3);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const int d : {2, 3}) {
    Vector p(d * 300);
    for (Eigen::Index a = 0; a < p.size(); ++a) p[a] = u(rng);
    out.emplace_back(p, d);
  }
  Vector line(2 * 200);  // one vertical line: every x the same
  for (int i = 0; i < 200; ++i) line.segment(2 * i, 2) << 3.0, 0.01 * ((i * 37) % 200);
  out.emplace_back(line, 2);
  return out;
}

TEST(PointIndex, NearestIsTheFirstKByDistanceThenIndex) {
  for (const auto& [p, d] : Layouts()) {
    const PointIndex index(p, d);
    for (int i = 0; i < index.size(); i += 7) {
      for (const int k : {1, 4, 8, 26}) {
        ASSERT_EQ(index.Nearest(i, k), BruteNearest(p, d, i, k)) << "d " << d << " i " << i;
      }
    }
  }
}

TEST(PointIndex, WithinRadiusIsEveryPointAtMostThatFar) {
  for (const auto& [p, d] : Layouts()) {
    const PointIndex index(p, d);
    for (int i = 0; i < index.size(); i += 5) {
      // On a grid of unit spacing, 1 and sqrt(2) fall exactly on neighbours.
      for (const double r : {0.0, 0.05, 1.0, std::sqrt(2.0), 0.3}) {
        ASSERT_EQ(index.WithinRadius(index.Point(i), r), BruteWithin(p, d, i, r))
            << "d " << d << " i " << i << " r " << r;
      }
    }
  }
}

TEST(PointIndex, CoincidentNodesOnOneLineAreNamed) {
  // Nodes on one vertical line (quadratic for the sweep along x this replaced), node 150 at
  // node 20's place.
  Scene s = testing::GridScene(2, 3);
  s.rest.resize(2 * 200);
  for (int i = 0; i < 200; ++i) s.rest.segment(2 * i, 2) << 1.0, 0.5 * i;
  s.rest.segment(2 * 150, 2) = s.rest.segment(2 * 20, 2);
  try {
    ValidateScene(s);
    FAIL() << "coincident nodes accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), "nodes[150]");
    EXPECT_NE(std::string(e.what()).find("same position as nodes[20]"), std::string::npos)
        << e.what();
  }
}

TEST(Candidates, EstimateBoundsTheCountBeforeGeneratingIt) {
  Scene s = testing::GridScene(2, 6);
  // Grid: 4 per node bounds the 8-neighbourhood's pairs.
  EXPECT_GE(EstimateCandidateCount(s, 1 << 30),
            static_cast<std::int64_t>(GenerateCandidates(s).size()));
  EXPECT_EQ(EstimateCandidateCount(s, 1 << 30), 4 * 36);
  // k nearest: k n.
  s.candidates.kind = CandidateSpec::Kind::kNearest;
  s.candidates.k = 5;
  EXPECT_EQ(EstimateCandidateCount(s, 1 << 30), 5 * 36);
  EXPECT_GE(5 * 36, static_cast<std::int64_t>(GenerateCandidates(s).size()));
  // A radius: counted exactly ...
  s.candidates.kind = CandidateSpec::Kind::kRadius;
  s.candidates.radius = 2.5;
  EXPECT_EQ(EstimateCandidateCount(s, 1 << 30),
            static_cast<std::int64_t>(GenerateCandidates(s).size()));
  // ... or up to the first count past the bound, which never exceeds the true count.
  const std::int64_t all = 36 * 35 / 2;
  s.candidates.radius = 100.0;
  const std::int64_t cut = EstimateCandidateCount(s, 100);
  EXPECT_GT(cut, 100);
  EXPECT_LE(cut, all);
  EXPECT_EQ(EstimateCandidateCount(s, all), all);
}

TEST(SwapPartners, SameAsComparingEveryPair) {
  const Problem problem(examples::Make("kidney-2d"));
  const double radius = 0.75;
  const auto partners = GeneticSearch::SwapPartners(problem, radius);
  const SpringGeometry& c = problem.candidates();
  const std::vector<int>& genes = problem.gene_candidates();
  const int d = problem.dimension();
  const Vector& rest = problem.scene().rest;
  auto mid = [&](int g) {
    const NodePair pair = c.pairs[genes[g]];
    return Vector(0.5 * (rest.segment(d * pair.first, d) + rest.segment(d * pair.second, d)));
  };
  int total = 0;
  for (int g = 0; g < static_cast<int>(genes.size()); ++g) {
    std::vector<int> expected;
    for (int h = 0; h < static_cast<int>(genes.size()); ++h) {
      const double limit = radius * std::min(c.rest_length[genes[g]], c.rest_length[genes[h]]);
      if (h != g && (mid(g) - mid(h)).squaredNorm() <= limit * limit) expected.push_back(h);
    }
    ASSERT_EQ(partners[g], expected) << "gene " << g;
    total += static_cast<int>(expected.size());
  }
  EXPECT_GT(total, static_cast<int>(genes.size()));  // the check saw partners
}

}  // namespace
}  // namespace springfit
