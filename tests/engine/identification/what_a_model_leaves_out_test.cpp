// What a model leaves out (issue 49 item 7; docs/ARCHITECTURE.md, "What a model leaves out"):
// on random extreme spring models the reference's topology comes back, up to what the load
// cases cannot tell.
#include <cmath>
#include <set>
#include <string>

#include <Eigen/QR>

#include <gtest/gtest.h>

#include "engine/api/identify.h"
#include "engine/api/result.h"
#include "tests/test_scenes.h"

namespace springfit {
namespace {

// Whether the springs hold the nodes as one rigid body (the rigidity matrix's rank is d n less
// the rigid motions).
bool Rigid(const Scene& s, const std::vector<NodePair>& springs) {
  const int d = s.dimension;
  Eigen::MatrixXd r =
      Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(springs.size()), d * s.node_count());
  for (std::size_t m = 0; m < springs.size(); ++m) {
    const auto& [a, b] = springs[m];
    for (int k = 0; k < d; ++k) {
      const double t = s.rest[d * b + k] - s.rest[d * a + k];
      r(static_cast<Eigen::Index>(m), d * a + k) = -t;
      r(static_cast<Eigen::Index>(m), d * b + k) = t;
    }
  }
  const int rigid = d == 2 ? 3 : 6;
  return Eigen::FullPivHouseholderQR<Eigen::MatrixXd>(r).rank() == d * s.node_count() - rigid;
}

// A grid's springs with a random third dropped where the rest stay rigid, stiffness
// log-uniform over `spread` around 1.
Scene RandomRigidScene(int dimension, int n, std::uint64_t seed, double spread) {
  const double drop = 0.3;
  Scene s = testing::GridScene(dimension, n);
  testing::TestRandom random(seed);
  std::vector<NodePair> kept = s.reference.springs;
  for (std::size_t m = 0; m < kept.size();) {
    if (random.Uniform() < drop) {
      std::vector<NodePair> trial = kept;
      trial.erase(trial.begin() + static_cast<std::ptrdiff_t>(m));
      if (Rigid(s, trial)) {
        kept = std::move(trial);
        continue;
      }
    }
    ++m;
  }
  std::vector<double> k;
  for (std::size_t m = 0; m < kept.size(); ++m)
    k.push_back(std::pow(spread, random.Uniform() - 0.5));
  s.reference.springs = kept;
  s.reference.stiffness = k;
  return s;
}

// The springs the load cases cannot tell apart, by the run's identifiability report.
std::set<NodePair> Undetermined(const IdentifiabilityReport& report) {
  std::set<NodePair> out(report.unidentifiable.begin(), report.unidentifiable.end());
  out.insert(report.unseen.begin(), report.unseen.end());
  for (const DependentGroup& g : report.groups) out.insert(g.springs.begin(), g.springs.end());
  return out;
}

// Random rigid spring models (a quarter to a third of the grid's springs dropped, stiffness
// log-uniform over a spread of 100 or 10^4), 2D and 3D: the default strategy (hybrid) and
// direct return the reference's springs, and where they differ, every spring in the difference
// is one the load cases cannot tell (the report says so); no spring the data rules out stays.
TEST(WhatAModelLeavesOut, RandomRigidSpringModelsComeBackExactWhereTheLoadsTell) {
  int exact = 0, runs = 0;
  for (double spread : {1e2, 1e4}) {
    for (int dimension : {2, 3}) {
      for (std::uint64_t seed = 1; seed <= 10; ++seed) {
        const Scene scene = RandomRigidScene(dimension, dimension == 2 ? 5 : 3, seed, spread);
        for (Strategy strategy : {Strategy::kDefault, Strategy::kDirect}) {
          Scene s = scene;
          s.search.strategy = strategy;
          const Problem p = Problem::Build(s);
          const IdentificationResult r =
              RunIdentification(p, ResolveSearchOptions(s.search, p.gene_count()));
          const std::string where = "spread " + std::to_string(spread) + ", " +
                                    std::to_string(dimension) + "D, seed " + std::to_string(seed) +
                                    ", " + (strategy == Strategy::kDirect ? "direct" : "default");
          ASSERT_TRUE(r.difference) << where;
          EXPECT_LE(r.evaluation.normalized_error, 1e-9) << where;
          ++runs;
          if (r.difference->hamming() == 0) {
            ++exact;
            continue;
          }
          const std::set<NodePair> undetermined = Undetermined(r.identifiability);
          for (const NodePair& e : r.difference->extra)
            EXPECT_TRUE(undetermined.count(e)) << where << ": extra " << e.first << "-" << e.second;
          for (const NodePair& e : r.difference->missing)
            EXPECT_TRUE(undetermined.count(e))
                << where << ": missing " << e.first << "-" << e.second;
        }
      }
    }
  }
  // (Measured: all 80 runs exact; a difference the report explains would still pass.)
  EXPECT_GE(exact, runs * 3 / 4);
}

}  // namespace
}  // namespace springfit
