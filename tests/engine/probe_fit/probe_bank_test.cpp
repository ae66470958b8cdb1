// The probe bank (engine/probe_fit/probe_bank.h): every support loaded by every family in every
// direction, with a held-out part; drawn supports on a 3D boundary hold every rigid motion.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <vector>

#include <Eigen/Eigenvalues>

#include "engine/probe_fit/generalization.h"
#include "engine/probe_fit/nonlinear_solves.h"
#include "engine/probe_fit/probe_bank.h"
#include "engine/probe_fit/tool_pushes.h"
#include "engine/problem/baseline_evaluation.h"
#include "engine/problem/rest_stiffness.h"
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
    if (bank.supports[s].tool()) continue;  // a tool load's own (ToolLoads... below)
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
      EXPECT_GT(count, 0) << "support " << s << " family " << response::ProbeFamilyName(family);
      EXPECT_GT(choosing, 0);
      EXPECT_GT(fitted, 0);
      // Both directions of the plane are loaded.
      const Eigen::SelfAdjointEigenSolver<Matrix> eig(directions);
      EXPECT_GT(eig.eigenvalues()[0], 0.05 * eig.eigenvalues()[1])
          << response::ProbeFamilyName(family);
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
    if (s.user || s.tool()) continue;
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

// Tool loads are imposed displacements: a push holds its base support and one boundary node, a
// grasp three neighbouring ones, moved in together along the first's inward normal by the bank's
// amplitude, with no force; the reference takes that shape; each base support's pushes and
// grasps have every role (the held-out ones in the certificate's bank, which judges them); an MSS
// reference, without a surface, has none.
TEST(ProbeBank, ToolLoadsHoldTheirNodesAtTheAmplitudeAlongTheInwardNormal) {
  const Problem problem(examples::Make("fem-kidney-2d"));
  const SparseMatrix k = ReferenceRestStiffness(problem);
  ProbeOptions options;
  options.fit_grasps = true;  // (so that the grasps are in the fit's bank, with every role)
  const ProbeBanks banks = MakeProbeBanks(problem, k, options);
  const ProbeBank& bank = banks.fit;
  const int d = problem.dimension();
  const double h = bank.amplitude;
  const Surface surface = AnySurface(problem.scene());
  std::vector<int> bases;  // per support: its base support (itself when not a tool's)
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    const Support& support = bank.supports[s];
    if (!support.tool()) {
      bases.push_back(static_cast<int>(s));
      continue;
    }
    EXPECT_FALSE(support.user);
    // The base: the one support before it that holds every node it holds but the tool's.
    int base = -1;
    for (std::size_t b = 0; b < s && base < 0; ++b) {
      std::vector<bool> with_tool = bank.supports[b].constrained;
      for (int node : support.tool_nodes) with_tool[static_cast<std::size_t>(node)] = true;
      if (!bank.supports[b].tool() && with_tool == support.constrained) base = static_cast<int>(b);
    }
    ASSERT_GE(base, 0) << support.description;
    bases.push_back(base);
  }
  // Per base support and tool family: fitted and choosing loads.
  std::map<std::pair<int, ProbeFamily>, std::pair<int, int>> roles;
  for (const Probe& p : bank.probes) {
    if (!IsToolFamily(p.family)) continue;
    const Support& support = bank.supports[static_cast<std::size_t>(p.support)];
    const std::vector<int>& nodes = support.tool_nodes;
    ASSERT_EQ(nodes.size(), p.family == ProbeFamily::kPush ? 1u : 3u);
    EXPECT_EQ(p.force.norm(), 0.0);
    ASSERT_EQ(p.prescribed.size(), p.reference.size());
    const Vector inward = -surface.normal.segment(d * nodes[0], d);
    EXPECT_NEAR(inward.norm(), 1.0, 1e-12);
    for (int node : nodes) {
      EXPECT_TRUE(support.constrained[static_cast<std::size_t>(node)]);
      EXPECT_LT((p.prescribed.segment(d * node, d) - h * inward).norm(), 1e-12 * h) << node;
      EXPECT_LT((p.reference.segment(d * node, d) - p.prescribed.segment(d * node, d)).norm(),
                1e-12 * h);
    }
    EXPECT_NEAR(p.prescribed.norm(), h * std::sqrt(static_cast<double>(nodes.size())), 1e-12 * h);
    // The reference takes the tool's shape: its elastic force vanishes off the held nodes.
    const Vector residual = k * p.reference;
    for (int n = 0; n < problem.scene().node_count(); ++n) {
      if (!support.constrained[static_cast<std::size_t>(n)]) {
        EXPECT_LT(residual.segment(d * n, d).norm(), 1e-8 * (k * p.prescribed).norm()) << n;
      }
    }
    auto& [fitted, choosing] = roles[{bases[static_cast<std::size_t>(p.support)], p.family}];
    fitted += p.role == ProbeRole::kFit;
    choosing += p.role == ProbeRole::kSelect;
  }
  int held_out = 0, base_count = 0;
  for (std::size_t s = 0; s < bank.supports.size(); ++s) {
    if (bank.supports[s].tool()) continue;
    ++base_count;
    for (const ProbeFamily family : {ProbeFamily::kPush, ProbeFamily::kGrasp}) {
      const auto [fitted, choosing] = roles[{static_cast<int>(s), family}];
      EXPECT_GT(fitted, 0) << bank.supports[s].description;
      EXPECT_GT(choosing, 0) << bank.supports[s].description;
      held_out +=
          (family == ProbeFamily::kPush ? options.pushes : options.grasps) - fitted - choosing;
    }
  }
  EXPECT_EQ(static_cast<int>(roles.size()), 2 * base_count);
  // The held-out tool loads are judged by the certificate: its table counts them.
  const std::optional<std::vector<double>> baseline = BaselineGeneWeights(problem);
  ASSERT_TRUE(baseline);
  const SpringModel model = ModelOfWeights(problem, *baseline);
  ToolPushOptions push_options;
  push_options.amplitudes = {1.0};
  const std::vector<ToolPushErrors> judged =
      Certifier(problem, bank, banks.held_out, k).JudgeToolPushes(model, model, push_options);
  ASSERT_EQ(judged.size(), 1u);
  EXPECT_EQ(judged[0].model.probes + judged[0].reference_failed, held_out);
  EXPECT_EQ(judged[0].pushes + judged[0].grasps, judged[0].model.probes);
  EXPECT_GT(judged[0].grasps, 0);

  // By default the grasps are the certificate's alone: none in the fit's bank, a quarter of
  // them (rounded up) made and judged.
  const ProbeBanks defaults = MakeProbeBanks(problem, k, ProbeOptions{});
  int default_pushes_held = 0;
  std::map<int, int> seen;  // per base support: its pushes in the fit's bank
  for (const Probe& p : defaults.fit.probes) {
    EXPECT_NE(p.family, ProbeFamily::kGrasp);
    if (p.family == ProbeFamily::kPush) ++seen[bases[static_cast<std::size_t>(p.support)]];
  }
  for (const auto& [base, pushes] : seen) default_pushes_held += ProbeOptions{}.pushes - pushes;
  const std::vector<ToolPushErrors> judged_default =
      Certifier(problem, defaults.fit, defaults.held_out, k)
          .JudgeToolPushes(model, model, push_options);
  ASSERT_EQ(judged_default.size(), 1u);
  EXPECT_EQ(judged_default[0].grasps + judged_default[0].reference_failed,
            base_count * ((ProbeOptions{}.grasps + 3) / 4));
  EXPECT_EQ(judged_default[0].pushes, default_pushes_held);

  const Problem mss(examples::Make("paper-iso-5x5"));
  const ProbeBanks none = MakeProbeBanks(mss, ReferenceRestStiffness(mss), options);
  for (const Probe& p : none.fit.probes) {
    EXPECT_NE(p.family, ProbeFamily::kPush);
    EXPECT_NE(p.family, ProbeFamily::kGrasp);
  }
}

}  // namespace
}  // namespace springfit::response
