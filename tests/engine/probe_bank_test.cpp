// The probe bank (engine/probe_fit/probe_bank.h): every support loaded by every family in every
// direction, with a held-out part; drawn supports on a 3D boundary hold every rigid motion.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include <Eigen/Eigenvalues>

#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/nonlinear_solves.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/rest_stiffness.h"
#include "engine/probe_fit/tool_pushes.h"
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
    if (bank.supports[s].tool_node >= 0) continue;  // a push's own (ToolPushes... below)
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
    if (s.user || s.tool_node >= 0) continue;
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

// Tool pushes (family push) are imposed displacements: each holds its base support and its
// pushed node, which moves in along the inward normal by the bank's amplitude, with no force;
// the reference takes that shape; each base support's pushes have every role (the held-out ones
// in the certificate's bank); an MSS reference, without a surface, has none.
TEST(ProbeBank, ToolPushesHoldTheirNodeAtTheAmplitudeAlongTheInwardNormal) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  ProbeOptions options;
  const ProbeBanks banks = MakeProbeBanks(problem, k, options);
  const ProbeBank& bank = banks.fit;
  const int d = problem.dimension();
  const Surface surface = AnySurface(problem.scene());
  std::vector<int> bases;  // per support: its base support (itself when not a push's)
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    const Support& support = bank.supports[s];
    if (support.tool_node < 0) {
      bases.push_back(static_cast<int>(s));
      continue;
    }
    EXPECT_FALSE(support.user);
    EXPECT_TRUE(support.constrained[static_cast<std::size_t>(support.tool_node)]);
    // The base: the one support before it that holds every node it holds but the tool's.
    int base = -1;
    for (std::size_t b = 0; b < s && base < 0; ++b) {
      std::vector<bool> with_tool = bank.supports[b].constrained;
      with_tool[static_cast<std::size_t>(support.tool_node)] = true;
      if (bank.supports[b].tool_node < 0 && with_tool == support.constrained)
        base = static_cast<int>(b);
    }
    ASSERT_GE(base, 0) << support.description;
    bases.push_back(base);
  }
  std::vector<int> fitted(bank.supports.size(), 0), choosing(bank.supports.size(), 0);
  int pushes = 0;
  for (const Probe& p : bank.probes) {
    if (p.family != ProbeFamily::kPush) continue;
    ++pushes;
    const Support& support = bank.supports[static_cast<std::size_t>(p.support)];
    const int node = support.tool_node;
    ASSERT_GE(node, 0);
    EXPECT_EQ(p.force.norm(), 0.0);
    ASSERT_EQ(p.prescribed.size(), p.reference.size());
    EXPECT_NEAR(p.prescribed.norm(), bank.amplitude, 1e-12 * bank.amplitude);
    const Vector inward = -surface.normal.segment(d * node, d);
    EXPECT_NEAR(p.prescribed.segment(d * node, d).dot(inward), bank.amplitude,
                1e-12 * bank.amplitude);
    EXPECT_LT((p.reference.segment(d * node, d) - p.prescribed.segment(d * node, d)).norm(),
              1e-12 * bank.amplitude);
    // The reference takes the push's shape: its elastic force vanishes off the held nodes.
    const Vector residual = k * p.reference;
    for (int n = 0; n < problem.scene().node_count(); ++n) {
      if (!support.constrained[static_cast<std::size_t>(n)]) {
        EXPECT_LT(residual.segment(d * n, d).norm(), 1e-8 * (k * p.prescribed).norm()) << n;
      }
    }
    const int base = bases[static_cast<std::size_t>(p.support)];
    fitted[static_cast<std::size_t>(base)] += p.role == ProbeRole::kFit;
    choosing[static_cast<std::size_t>(base)] += p.role == ProbeRole::kSelect;
  }
  EXPECT_GT(pushes, 0);
  int held_out_pushes = 0;
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    if (bank.supports[s].tool_node >= 0) continue;
    EXPECT_GT(fitted[s], 0) << bank.supports[s].description;
    EXPECT_GT(choosing[s], 0) << bank.supports[s].description;
    held_out_pushes += options.pushes - fitted[s] - choosing[s];
  }
  // The held-out pushes are judged by the certificate: its tool-push table counts them.
  const std::optional<std::vector<double>> baseline = BaselineGeneWeights(problem);
  ASSERT_TRUE(baseline);
  const SpringModel model = ModelOfWeights(problem, *baseline);
  ToolPushOptions push_options;
  push_options.amplitudes = {1.0};
  const std::vector<ToolPushErrors> judged =
      Certifier(problem, bank, banks.held_out, k).JudgeToolPushes(model, model, push_options);
  ASSERT_EQ(judged.size(), 1u);
  EXPECT_EQ(judged[0].model.probes + judged[0].reference_failed, held_out_pushes);

  const Problem mss(examples::Make("paper-iso-5x5"));
  const ProbeBanks none = MakeProbeBanks(mss, ReferenceRestStiffness(mss), options);
  for (const Probe& p : none.fit.probes) EXPECT_NE(p.family, ProbeFamily::kPush);
}

}  // namespace
}  // namespace springfit::response
