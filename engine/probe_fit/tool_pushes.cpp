#include "engine/probe_fit/tool_pushes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "engine/runtime/options_check.h"

namespace springfit::response {
namespace {

// The elastic force of springs on `nodes` at displacement u, summed: over each node's springs
// k (L - l) (x_node - x_other) / L, the gradient of their energy in the node's position (a
// spring between two of the nodes cancels, as it does in the tool's own force).
Vector SpringReaction(const SpringSolverInput& input, const Vector& rest, const Vector& u,
                      const std::vector<int>& nodes, int d) {
  Vector r = Vector::Zero(d);
  const SpringGeometry& g = input.geometry;
  for (int node : nodes) {
    for (int s = 0; s < input.springs.size(); ++s) {
      const int e = input.springs.index[static_cast<std::size_t>(s)];
      const NodePair pair = g.pairs[static_cast<std::size_t>(e)];
      if (pair.first != node && pair.second != node) continue;
      const int other = pair.first == node ? pair.second : pair.first;
      const Vector separation = (rest.segment(d * node, d) + u.segment(d * node, d)) -
                                (rest.segment(d * other, d) + u.segment(d * other, d));
      const double length = separation.norm();
      if (!(length > 0.0)) continue;
      r += input.springs.stiffness[static_cast<std::size_t>(s)] *
           (length - g.rest_length[static_cast<std::size_t>(e)]) * separation / length;
    }
  }
  return r;
}

// The FEM reference's elastic force on `nodes` at u, summed: the gradient of its energy there,
// from a solver that leaves them free (no external force).
Vector FemReaction(const fem::FemModel& fem, const std::vector<bool>& constrained, const Vector& u,
                   const std::vector<int>& nodes, int d) {
  std::vector<bool> with_nodes_free = constrained;
  for (int node : nodes) with_nodes_free[static_cast<std::size_t>(node)] = false;
  const FreeNodes free = FreeNodes::FromConstrained(with_nodes_free);
  fem::FemEquilibriumSolver solver(fem, free);
  Vector gradient;
  solver.EnergyAndGradient(Vector::Zero(u.size()), u, &gradient, false);
  Vector r = Vector::Zero(d);
  for (int node : nodes)
    r += gradient.segment(d * free.free_index[static_cast<std::size_t>(node)], d);
  return r;
}

struct PushResult {
  double error = std::numeric_limits<double>::quiet_NaN();  // NaN: the reference failed
  double force_error = std::numeric_limits<double>::quiet_NaN();
  double force_ratio = std::numeric_limits<double>::quiet_NaN();
  bool inverted = false;
};

}  // namespace

void ToolPushOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  CheckAmplitudes(check, amplitudes);
  check.Require(max_tool_loads >= 1, "max_tool_loads", max_tool_loads, "value >= 1");
}

std::vector<ToolPushErrors> JudgeToolPushes(const Problem& problem, const ProbeBank& bank,
                                            const SpringModel& model, const SpringModel& baseline,
                                            const ToolPushOptions& options,
                                            Interruption* interruption, WorkerPool* pool) {
  options.Validate();
  const Scene& scene = problem.scene();
  if (scene.reference.kind != Reference::Kind::kFem) return {};
  const int d = scene.dimension;
  std::vector<int> all;
  for (std::size_t p = 0; p < bank.probes.size(); ++p)
    if (IsToolFamily(bank.probes[p].family)) all.push_back(static_cast<int>(p));
  const std::vector<int> pushed = EvenlySpread(all, options.max_tool_loads);
  if (pushed.empty()) return {};
  const std::size_t depths = options.amplitudes.size();
  const ReferenceModel reference(problem);
  const SpringSolverInput model_input(scene, model), baseline_input(scene, baseline);
  // Per depth and pushed node: the model's and the baseline's results.
  std::vector<std::vector<PushResult>> model_results(depths,
                                                     std::vector<PushResult>(pushed.size()));
  std::vector<std::vector<PushResult>> baseline_results = model_results;

  RunSlots(
      pool, static_cast<int>(pushed.size()),
      [&](int slot) {
        const auto i = static_cast<std::size_t>(slot);
        const Probe& probe = bank.probes[static_cast<std::size_t>(pushed[i])];
        const Support& support = bank.supports[static_cast<std::size_t>(probe.support)];
        const std::vector<int>& nodes = support.tool_nodes;
        const std::vector<bool>& held = support.constrained;
        const FreeNodes free = FreeNodes::FromConstrained(held);
        ReferenceSolver reference_solver(reference.fem, reference.springs, free, problem,
                                         interruption);
        SpringResponse model_solver(model_input, free, LoadStepSolverOptions(problem),
                                    interruption);
        SpringResponse baseline_solver(baseline_input, free, LoadStepSolverOptions(problem),
                                       interruption);
        const Vector force = Vector::Zero(scene.rest.size());
        for (std::size_t a = 0; a < depths; ++a) {
          const Vector prescribed = options.amplitudes[a] * probe.prescribed;
          const std::optional<Vector> u_ref = reference_solver.SolveAt(
              ScaledLoad{force, prescribed}, probe.reference, options.amplitudes[a]);
          if (!u_ref) continue;  // (NaN: left out)
          const Vector r_ref = FemReaction(*reference.fem, held, *u_ref, nodes, d);
          const auto judge = [&](SpringResponse& solver, const SpringSolverInput& input) {
            PushResult r;
            const std::optional<Vector> u = solver.Solve(force, prescribed);
            if (!u) {
              r.error = r.force_error = std::numeric_limits<double>::infinity();
              return r;
            }
            r.error = RelativeError(*u, *u_ref, free, d);
            const Vector reaction = SpringReaction(input, scene.rest, *u, nodes, d);
            r.force_error = (reaction - r_ref).norm() / r_ref.norm();
            r.force_ratio = reaction.norm() / r_ref.norm();
            r.inverted = InvertedElements(scene, *u) > 0;
            return r;
          };
          model_results[a][i] = judge(model_solver, model_input);
          baseline_results[a][i] = judge(baseline_solver, baseline_input);
        }
      },
      [interruption] {
        if (interruption) interruption->Check();
      });
  ThrowIfInterrupted(interruption);

  std::vector<ToolPushErrors> out;
  for (std::size_t a = 0; a < depths; ++a) {
    ToolPushErrors e;
    e.amplitude = options.amplitudes[a];
    e.depth = options.amplitudes[a] * bank.amplitude;
    std::vector<double> me, be, mf, bf, mr, br;
    for (std::size_t i = 0; i < pushed.size(); ++i) {
      const PushResult& m = model_results[a][i];
      const PushResult& b = baseline_results[a][i];
      if (std::isnan(m.error)) {
        ++e.reference_failed;
        continue;
      }
      ++(bank.probes[static_cast<std::size_t>(pushed[i])].family == ProbeFamily::kGrasp ? e.grasps
                                                                                        : e.pushes);
      me.push_back(m.error);
      be.push_back(b.error);
      mf.push_back(m.force_error);
      bf.push_back(b.force_error);
      mr.push_back(m.force_ratio);
      br.push_back(b.force_ratio);
      e.model_inverted += m.inverted ? 1 : 0;
      e.baseline_inverted += b.inverted ? 1 : 0;
    }
    e.model = Summarize(me);
    e.baseline = Summarize(be);
    e.model_force = Summarize(mf);
    e.baseline_force = Summarize(bf);
    e.model_force_ratio = Summarize(mr).median;
    e.baseline_force_ratio = Summarize(br).median;
    out.push_back(e);
  }
  return out;
}

}  // namespace springfit::response
