// The probe bank (engine/probe_fit/probe_bank.h): every support loaded by every family in every
// direction, with a held-out part; drawn supports on a 3D boundary hold every rigid motion.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <Eigen/Eigenvalues>

#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/rest_stiffness.h"
#include "engine/problem/baseline_evaluation.h"
#include "io/example_catalog.h"
#include "proto/names.h"

namespace springfit::response {
namespace {

TEST(ProbeBank, EverySupportHasEveryFamilyInEveryDirectionAndAHeldOutPart) {
  const Problem problem(examples::Make("fem-plate-5x5"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBanks banks = MakeProbeBanks(problem, k, ProbeOptions{});
  const ProbeBank& bank = banks.fit;
  ASSERT_GE(bank.supports.size(), 4u);  // the user's two and drawn ones
  // (How many of each group are held out: the certificate's counts, per support and family.)
  EXPECT_GT(banks.held_out.size(), 0);
  int user = 0;
  for (const Support& s : bank.supports) user += s.user;
  EXPECT_EQ(user, 2);
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    for (ProbeFamily family : {ProbeFamily::kPoint, ProbeFamily::kPatch, ProbeFamily::kBody}) {
      int count = 0, choosing = 0, fitted = 0;
      Matrix directions = Matrix::Zero(2, 2);  // sum of f f^T over the family's forces
      for (const Probe& p : bank.probes) {
        if (p.support != static_cast<int>(s) || p.family != family) continue;
        ++count;
        choosing += p.role == ProbeRole::kSelect;
        fitted += p.role == ProbeRole::kFit;
        for (int node = 0; node < problem.scene().node_count(); ++node) {
          const Vector f = p.force.segment(2 * node, 2);
          directions += f * f.transpose() / std::max(f.squaredNorm(), 1e-300);
          // No load on a held node.
          if (bank.supports[s].constrained[static_cast<std::size_t>(node)]) {
            EXPECT_EQ(f.norm(), 0.0);
          }
        }
      }
      EXPECT_GT(count, 0) << "support " << s << " family " << proto::ProbeFamilyName(family);
      EXPECT_GT(choosing, 0);
      EXPECT_GT(fitted, 0);
      // Both directions of the plane are loaded.
      const Eigen::SelfAdjointEigenSolver<Matrix> eig(directions);
      EXPECT_GT(eig.eigenvalues()[0], 0.05 * eig.eigenvalues()[1])
          << proto::ProbeFamilyName(family);
    }
  }
  // Same options, same bank.
  const ProbeBank again = MakeProbeBanks(problem, k, ProbeOptions{}).fit;
  ASSERT_EQ(again.probes.size(), bank.probes.size());
  for (std::size_t p = 0; p < bank.probes.size(); ++p) {
    EXPECT_EQ(again.probes[p].force, bank.probes[p].force);
    EXPECT_EQ(again.probes[p].role, bank.probes[p].role);
  }
}

// Supports drawn from a 3D boundary hold every rigid motion: a patch along one edge of the
// block would leave the rotation about it free for every model (the held-out E of
// 1e17), and the closed-form baseline, a sound model, has a finite error on every probe.
TEST(ProbeBank, DrawnSupportsOnA3DBoundaryHoldEveryRigidMotion) {
  const Problem problem(examples::Make("fem-block-3d"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  const ProbeBanks banks = MakeProbeBanks(problem, k, ProbeOptions{});
  const ProbeBank& bank = banks.fit;
  const int d = problem.dimension();
  int drawn = 0;
  for (const Support& s : bank.supports) {
    if (s.user) continue;
    ++drawn;
    std::vector<Eigen::Vector3d> held;
    for (int node = 0; node < problem.scene().node_count(); ++node)
      if (s.constrained[static_cast<std::size_t>(node)])
        held.push_back(problem.scene().rest.segment<3>(d * node));
    ASSERT_GE(held.size(), 3u);
    double area = 0.0, longest = 0.0;
    for (const auto& b : held) longest = std::max(longest, (b - held[0]).norm());
    for (const auto& b : held)
      for (const auto& c : held) area = std::max(area, (b - held[0]).cross(c - held[0]).norm());
    EXPECT_GT(area, 0.05 * longest * longest) << s.description;
  }
  EXPECT_GE(drawn, 1);
  const std::optional<std::vector<double>> baseline = BaselineGeneWeights(problem);
  ASSERT_TRUE(baseline);
  const SparseMatrix baseline_k = SpringRestStiffness(problem, *baseline);
  const Generalization g =
      Certifier(problem, bank, banks.held_out, k).Certify(*baseline, baseline_k);
  EXPECT_TRUE(std::isfinite(g.model_held_out.p95)) << g.model_held_out.p95;
  EXPECT_GT(g.lambda_min, 0.0);
}

}  // namespace
}  // namespace springfit::response
