#include "engine/probe_fit/probe_bank.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <map>
#include <numeric>
#include <stdexcept>

#include <fmt/format.h>

#include "engine/fem/fem_model.h"
#include "engine/probe_fit/nonlinear_solves.h"
#include "engine/problem/small_strain.h"
#include "engine/problem/support_system.h"
#include "engine/runtime/input_error.h"
#include "engine/runtime/options_check.h"
#include "engine/search/random_stream.h"

namespace springfit::response {
namespace {

// Each (support, family) group of generated probes has at least one probe per role.
constexpr int kGroupMinimum = 3;
constexpr int kGeneratedFamilies = 3;  // point, patch, body

// A direction drawn uniformly on the unit circle or sphere (Box-Muller on the stream's own
// uniform draws, so the same seed gives the same directions everywhere).
Vector RandomDirection(int d, RandomStream& random) {
  Vector v(d);
  do {
    for (int c = 0; c < d; ++c) {
      const double u1 = 1.0 - random.Uniform();  // (0, 1]
      const double u2 = random.Uniform();
      v[c] = std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
    }
  } while (v.norm() < 1e-12);
  return v / v.norm();
}

// The FEM mesh's boundary: facets of one element, with outward normals summed per node.
Surface FemSurface(const Scene& scene) {
  const int d = scene.dimension;
  const int n = scene.node_count();
  std::map<std::vector<int>, std::pair<int, int>> facets;  // facet -> (count, opposite)
  fem::ForEachFacet(scene.reference.fem, d,
                    [&](std::size_t, const std::vector<int>& facet, int opposite) {
                      auto [it, inserted] = facets.try_emplace(facet, 0, opposite);
                      ++it->second.first;
                    });
  Surface s;
  s.normal = Vector::Zero(d * n);
  std::vector<bool> on(static_cast<std::size_t>(n), false);
  const auto x = [&](int node) { return Vector(scene.rest.segment(d * node, d)); };
  for (const auto& [facet, info] : facets) {
    if (info.first != 1) continue;
    Vector normal(d);
    if (d == 2) {
      const Vector t = x(facet[1]) - x(facet[0]);
      normal << t[1], -t[0];
    } else {
      const Eigen::Vector3d a = x(facet[1]) - x(facet[0]);
      const Eigen::Vector3d b = x(facet[2]) - x(facet[0]);
      normal = a.cross(b);
    }
    if (normal.dot(x(info.second) - x(facet[0])) > 0.0) normal = -normal;
    for (int node : facet) {
      s.normal.segment(d * node, d) += normal;
      on[static_cast<std::size_t>(node)] = true;
    }
  }
  for (int node = 0; node < n; ++node) {
    if (!on[static_cast<std::size_t>(node)]) continue;
    s.nodes.push_back(node);
    const double length = s.normal.segment(d * node, d).norm();
    if (length > 0.0) s.normal.segment(d * node, d) /= length;
  }
  return s;
}

// The `count` nodes of `pool` nearest to node `centre` (centre first), ties by index.
std::vector<int> Nearest(const Scene& scene, const std::vector<int>& pool, int centre, int count) {
  const int d = scene.dimension;
  std::vector<std::pair<double, int>> by_distance;
  for (int node : pool)
    by_distance.emplace_back(
        (scene.rest.segment(d * node, d) - scene.rest.segment(d * centre, d)).squaredNorm(), node);
  const auto end = by_distance.begin() + std::min<std::ptrdiff_t>(count, by_distance.size());
  std::partial_sort(by_distance.begin(), end, by_distance.end());
  std::vector<int> nodes;
  for (auto it = by_distance.begin(); it != end; ++it) nodes.push_back(it->second);
  return nodes;
}

// Lumped nodal volumes: each element's volume shared equally by its nodes (1 per node without
// elements).
Vector NodalVolumes(const Scene& scene) {
  const int n = scene.node_count();
  if (scene.reference.kind != Reference::Kind::kFem) return Vector::Ones(n);
  const fem::FemModel model = fem::FemModel::Build(scene);
  Vector v = Vector::Zero(n);
  const auto add = [&](const auto& elements) {
    for (const auto& e : elements)
      for (int node : e.nodes) v[node] += e.volume / static_cast<double>(e.nodes.size());
  };
  if (scene.dimension == 2)
    add(model.elements2());
  else
    add(model.elements3());
  return v;
}

// The roles of probes [begin, end): shuffled, the first held out (`held` set), the next chosen
// on, the rest fitted.
void AssignRoles(std::vector<Probe>& probes, std::vector<bool>& held, std::size_t begin,
                 const ProbeOptions& options, RandomStream& random) {
  const std::size_t count = probes.size() - begin;
  held.resize(probes.size(), false);
  if (count == 0) return;
  std::vector<std::size_t> order(count);
  std::iota(order.begin(), order.end(), begin);
  for (std::size_t i = count; i > 1; --i)
    std::swap(order[i - 1], order[static_cast<std::size_t>(random.Below(static_cast<int>(i)))]);
  const auto held_out =
      static_cast<std::size_t>(std::ceil(options.held_out_fraction * static_cast<double>(count)));
  const auto select =
      static_cast<std::size_t>(std::ceil(options.select_fraction * static_cast<double>(count)));
  for (std::size_t i = 0; i < count; ++i) {
    held[order[i]] = i < held_out;
    probes[order[i]].role =
        i >= held_out && i < held_out + select ? ProbeRole::kSelect : ProbeRole::kFit;
  }
}

// Whether holding `nodes` fixes every rigid motion: in 2D two distinct points, in 3D three not
// on one line (the triangle they span at least 5% of its longest side squared, so that a
// nearly straight row of nodes along an edge does not count).
bool HoldsRigidMotion(const Scene& scene, const std::vector<int>& nodes) {
  const int d = scene.dimension;
  if (nodes.size() < static_cast<std::size_t>(d)) return false;
  const auto at = [&](int node) { return scene.rest.segment(d * node, d); };
  const Vector a = at(nodes[0]);
  int far = nodes[0];
  double longest = 0.0;
  for (int node : nodes) {
    const double l = (at(node) - a).norm();
    if (l > longest) {
      longest = l;
      far = node;
    }
  }
  if (!(longest > 0.0)) return false;
  if (d == 2) return true;
  const Eigen::Vector3d ab = (at(far) - a).head<3>();
  for (int node : nodes) {
    const Eigen::Vector3d ac = (at(node) - a).head<3>();
    if (ab.cross(ac).norm() > 0.05 * longest * longest) return true;
  }
  return false;
}

}  // namespace

const char* ProbeFamilyName(ProbeFamily family) {
  switch (family) {
    case ProbeFamily::kPoint:
      return "point";
    case ProbeFamily::kPatch:
      return "patch";
    case ProbeFamily::kBody:
      return "body";
    case ProbeFamily::kNamed:
      return "named";
    case ProbeFamily::kMode:
      return "mode";
    case ProbeFamily::kPush:
      return "push";
    case ProbeFamily::kGrasp:
      return "grasp";
  }
  return "?";
}

void ProbeOptions::Validate(const std::string& owner) const {
  const OptionsCheck check(owner);
  check.Require(count >= 0, "count", count, "value >= 0");
  check.Require(extra_supports >= 0 && extra_supports <= 64, "extra_supports", extra_supports,
                "0 <= value <= 64");
  check.Require(pushes == 0 || (pushes >= kGroupMinimum && pushes <= 256), "pushes", pushes,
                "0, or 3 <= value <= 256");
  check.Require(grasps == 0 || (grasps >= kGroupMinimum && grasps <= 256), "grasps", grasps,
                "0, or 3 <= value <= 256");
  check.Require(support_fraction > 0.0 && support_fraction <= 0.5, "support_fraction",
                support_fraction, "0 < value <= 0.5");
  check.Require(select_fraction > 0.0 && select_fraction <= 0.5, "select_fraction", select_fraction,
                "0 < value <= 0.5");
  check.Require(held_out_fraction > 0.0 && held_out_fraction <= 0.5, "held_out_fraction",
                held_out_fraction, "0 < value <= 0.5");
  check.Require(named_weight >= 0.0 && named_weight < 1.0, "named_weight", named_weight,
                "0 <= value < 1");
  check.Require(soft_mode_weight >= 0.0 && named_weight + soft_mode_weight < 1.0,
                "soft_mode_weight", soft_mode_weight, "value >= 0 and named_weight + value < 1");
  check.Require(tool_weight >= 0.0 && named_weight + soft_mode_weight + tool_weight < 1.0,
                "tool_weight", tool_weight,
                "value >= 0 and named_weight + soft_mode_weight + value < 1");
}

int MinimumProbeCount(int user_supports, const ProbeOptions& options) {
  return kGroupMinimum * kGeneratedFamilies * (user_supports + options.extra_supports);
}

int MaximumToolCount(int user_supports, const ProbeOptions& options) {
  return (options.pushes + options.grasps) * (user_supports + options.extra_supports);
}

double ProbeBankBytes(long long probes, int nodes, int dimension) {
  return 2.0 * static_cast<double>(probes) * static_cast<double>(nodes) * dimension *
         static_cast<double>(sizeof(double));
}

namespace {

// MakeProbeBanks' steps, in the order they draw from the random stream (the same seed gives the
// same bank).
class BankBuilder {
 public:
  BankBuilder(const Problem& problem, const SparseMatrix& reference_stiffness,
              const ProbeOptions& options)
      : problem_(problem),
        scene_(problem.scene()),
        reference_stiffness_(reference_stiffness),
        options_(options),
        d_(scene_.dimension),
        n_(scene_.node_count()),
        random_(options.seed),
        surface_(AnySurface(scene_)) {
    bank_.boundary = surface_.nodes;
  }

  // The user's supports, one per distinct free set, and their systems.
  void AddUserSupports() {
    support_of_free_set_.assign(problem_.free_sets().size(), -1);
    for (std::size_t k = 0; k < problem_.load_cases().size(); ++k) {
      const int set = problem_.load_cases()[k].free_set;
      if (support_of_free_set_[static_cast<std::size_t>(set)] >= 0) continue;
      Support support;
      support.user = true;
      support.description = "load case '" + scene_.load_cases[k].name + "'";
      support.constrained.resize(static_cast<std::size_t>(n_));
      for (int node = 0; node < n_; ++node)
        support.constrained[static_cast<std::size_t>(node)] =
            problem_.free_sets()[static_cast<std::size_t>(set)]
                .free_index[static_cast<std::size_t>(node)] < 0;
      SupportSystem system(d_, support.constrained);
      if (!system.Factorize(reference_stiffness_))
        throw InputError(LoadCasePath(k) + ".fixed",
                         "the reference is not held by this load case's supports (a rigid motion "
                         "or a mechanism is left free): no probe can be solved on it");
      support_of_free_set_[static_cast<std::size_t>(set)] = static_cast<int>(bank_.supports.size());
      bank_.supports.push_back(std::move(support));
      systems_.push_back(std::move(system));
    }
  }

  // The named cases, all fitted; their median largest displacement sets the probes' amplitude.
  void AddNamedCases() {
    const std::size_t first = bank_.probes.size();
    for (std::size_t k = 0; k < problem_.load_cases().size(); ++k) {
      const PreparedLoadCase& lc = problem_.load_cases()[k];
      Probe probe;
      probe.family = ProbeFamily::kNamed;
      probe.support = support_of_free_set_[static_cast<std::size_t>(lc.free_set)];
      probe.named_case = static_cast<int>(k);
      probe.force = lc.force;
      probe.prescribed = lc.prescribed;
      probe.reference =
          systems_[static_cast<std::size_t>(probe.support)].Displacement(lc.force, lc.prescribed);
      bank_.probes.push_back(std::move(probe));
    }
    std::vector<const Vector*> responses;
    for (std::size_t p = first; p < bank_.probes.size(); ++p)
      responses.push_back(&bank_.probes[p].reference);
    bank_.amplitude = LoadsSize(d_, responses);
    if (!(bank_.amplitude > 0.0)) bank_.amplitude = 0.05 * scene_.Bounds().Diagonal();
  }

  // Supports drawn from the boundary: patches around random boundary nodes that hold the
  // reference, each distinct.
  void DrawSupports() {
    const int patch_size =
        std::max(d_, static_cast<int>(std::lround(options_.support_fraction *
                                                  static_cast<double>(surface_.nodes.size()))));
    for (int s = 0, tries = 0;
         s < options_.extra_supports && tries < 4 * options_.extra_supports + 4; ++tries) {
      if (surface_.nodes.size() < static_cast<std::size_t>(patch_size) + 2) break;
      const int centre = surface_.nodes[static_cast<std::size_t>(
          random_.Below(static_cast<int>(surface_.nodes.size())))];
      Support support;
      support.constrained.assign(static_cast<std::size_t>(n_), false);
      const std::vector<int> patch = Nearest(scene_, surface_.nodes, centre, patch_size);
      // A patch along one line leaves the rotation about it free for every model, the reference
      // included (whose factorisation may still pass on round-off): such loads test nothing.
      if (!HoldsRigidMotion(scene_, patch)) continue;
      for (int node : patch) support.constrained[static_cast<std::size_t>(node)] = true;
      support.description = "boundary patch around node " + std::to_string(centre);
      bool duplicate = false;
      for (const Support& other : bank_.supports)
        duplicate |= other.constrained == support.constrained;
      if (duplicate) continue;
      SupportSystem system(d_, support.constrained);
      if (!system.Factorize(reference_stiffness_)) continue;  // too small a patch to hold it
      bank_.supports.push_back(std::move(support));
      systems_.push_back(std::move(system));
      ++s;
    }
  }

  // Generated probes on every support, family by family, each family's roles assigned.
  void AddGeneratedProbes() {
    const int supports = static_cast<int>(bank_.supports.size());
    int points = std::min<int>(static_cast<int>(surface_.nodes.size()), 24);
    int patches = 12;
    int bodies = d_ + 2;
    if (options_.count > 0) {
      const double per_support = static_cast<double>(options_.count) / supports;
      const auto share = [&](double fraction) {
        return std::max(kGroupMinimum, static_cast<int>(std::lround(fraction * per_support)));
      };
      points = share(0.6);
      patches = share(0.3);
      bodies = share(0.1);
    }
    const Vector volumes = NodalVolumes(scene_);
    for (int s = 0; s < supports; ++s) {
      const Support& support = bank_.supports[static_cast<std::size_t>(s)];
      std::vector<int> loadable;
      for (int node : surface_.nodes)
        if (!support.constrained[static_cast<std::size_t>(node)]) loadable.push_back(node);
      for (ProbeFamily family : {ProbeFamily::kPoint, ProbeFamily::kPatch, ProbeFamily::kBody}) {
        const std::size_t begin = bank_.probes.size();
        std::vector<Vector> forces;
        if (family == ProbeFamily::kPoint && !loadable.empty())
          forces = PointLoads(loadable, points);
        else if (family == ProbeFamily::kPatch && !loadable.empty())
          forces = PatchLoads(loadable, patches);
        else if (family == ProbeFamily::kBody)
          forces = BodyForces(support, volumes, bodies);
        for (const Vector& force : forces) Add(family, s, force);
        AssignRoles(bank_.probes, held_, begin, options_, random_);
      }
    }
  }

  // Tool loads on every support made so far (the user's and the drawn ones): boundary nodes
  // with a normal, free on it, evenly spread, each pushed in along its inward normal (family
  // push) or held with its two nearest such neighbours and moved in with them (family grasp);
  // each a support of its own, the loads of one family on one base support a group whose roles
  // are assigned as a family's.
  void AddToolProbes() {
    if (scene_.reference.kind != Reference::Kind::kFem) return;
    // (A family judged but not fitted (in 3D, ProbeOptions::fit_tools_in_3d; grasps,
    // ProbeOptions::fit_grasps): only as many as would be held out are made, each held out.)
    const bool fit_pushes = d_ == 2 || options_.fit_tools_in_3d;
    const bool fit_grasps = fit_pushes && options_.fit_grasps;
    const std::size_t bases = bank_.supports.size();
    // (Family by family, so that the pushes' roles do not depend on the grasps.)
    for (const ProbeFamily family : {ProbeFamily::kPush, ProbeFamily::kGrasp}) {
      const bool push = family == ProbeFamily::kPush;
      const bool fitted = push ? fit_pushes : fit_grasps;
      const int count = push ? options_.pushes : options_.grasps;
      if (count == 0) continue;
      const int made = fitted ? count
                              : static_cast<int>(std::ceil(options_.held_out_fraction *
                                                           static_cast<double>(count)));
      for (std::size_t s = 0; s < bases; ++s) {
        std::vector<int> pushable;
        for (int node : surface_.nodes)
          if (!bank_.supports[s].constrained[static_cast<std::size_t>(node)] &&
              surface_.normal.segment(d_ * node, d_).norm() > 0.5)
            pushable.push_back(node);
        if (pushable.size() < (push ? 1u : 3u)) continue;
        const std::size_t begin = bank_.probes.size();
        for (int node : EvenlySpread(pushable, made))
          AddTool(s, family, push ? std::vector<int>{node} : Nearest(scene_, pushable, node, 3),
                  -surface_.normal.segment(d_ * node, d_), !fitted);
        AssignRoles(bank_.probes, held_, begin, options_, random_);
        if (!fitted)
          for (std::size_t p = begin; p < held_.size(); ++p) held_[p] = true;
      }
    }
  }

  // Every probe's |u_ref|^2 over its support's free nodes; the held-out probes in a bank of
  // their own (the same supports), each part in the order the probes were made.
  std::pair<ProbeBank, ProbeBank> Finish() {
    held_.resize(bank_.probes.size(), false);
    ProbeBank fit, held_out;
    fit.supports = held_out.supports = std::move(bank_.supports);
    fit.boundary = held_out.boundary = std::move(bank_.boundary);
    fit.amplitude = held_out.amplitude = bank_.amplitude;
    for (std::size_t p = 0; p < bank_.probes.size(); ++p) {
      Probe& probe = bank_.probes[p];
      const Vector free = systems_[static_cast<std::size_t>(probe.support)].Gather(probe.reference);
      probe.reference_norm2 = free.squaredNorm();
      (held_[p] ? held_out : fit).probes.push_back(std::move(probe));
    }
    return {std::move(fit), std::move(held_out)};
  }

 private:
  // Forces on one boundary node: half along the inward normal (where there is one), half in a
  // random direction.
  std::vector<Vector> PointLoads(const std::vector<int>& loadable, int count) {
    std::vector<Vector> forces;
    for (int i = 0; i < count; ++i) {
      const int node =
          loadable[static_cast<std::size_t>(random_.Below(static_cast<int>(loadable.size())))];
      const Vector normal = surface_.normal.segment(d_ * node, d_);
      Vector force = Vector::Zero(d_ * n_);
      force.segment(d_ * node, d_) =
          i % 2 == 0 && normal.norm() > 0.5 ? Vector(-normal) : RandomDirection(d_, random_);
      forces.push_back(std::move(force));
    }
    return forces;
  }

  // One force spread on a boundary node and its nearest boundary neighbours (3 to 8 nodes).
  std::vector<Vector> PatchLoads(const std::vector<int>& loadable, int count) {
    std::vector<Vector> forces;
    for (int i = 0; i < count; ++i) {
      const int centre =
          loadable[static_cast<std::size_t>(random_.Below(static_cast<int>(loadable.size())))];
      const int size = 3 + random_.Below(6);
      const Vector direction = RandomDirection(d_, random_);
      Vector force = Vector::Zero(d_ * n_);
      for (int node : Nearest(scene_, loadable, centre, size))
        force.segment(d_ * node, d_) = direction;
      forces.push_back(std::move(force));
    }
    return forces;
  }

  // Uniform body forces (lumped by volume) along each axis, then in random directions.
  std::vector<Vector> BodyForces(const Support& support, const Vector& volumes, int count) {
    std::vector<Vector> forces;
    for (int i = 0; i < count; ++i) {
      const Vector direction = i < d_ ? Vector(Vector::Unit(d_, i)) : RandomDirection(d_, random_);
      Vector force = Vector::Zero(d_ * n_);
      for (int node = 0; node < n_; ++node) {
        if (support.constrained[static_cast<std::size_t>(node)]) continue;
        force.segment(d_ * node, d_) = volumes[node] * direction;
      }
      forces.push_back(std::move(force));
    }
    return forces;
  }

  // A generated probe on support `s`, scaled to the bank's amplitude (dropped when the
  // reference does not move under it).
  void Add(ProbeFamily family, int s, const Vector& force) {
    Probe probe;
    probe.family = family;
    probe.support = s;
    probe.reference = systems_[static_cast<std::size_t>(s)].Displacement(force, Vector());
    const double largest = LargestNodalDisplacement(d_, probe.reference);
    if (!(largest > 0.0)) return;
    const double scale = bank_.amplitude / largest;
    probe.force = force * scale;
    probe.reference *= scale;
    bank_.probes.push_back(std::move(probe));
  }

  // A tool load on base support `base`: `nodes` held and moved by the bank's amplitude along
  // the unit `direction` (the tool's depth is the loads' size; the body beyond it may move
  // further, as a cantilever's tip does). Dropped when the base support with the nodes held
  // does not hold the reference. `held_out_only`: the reference solved through the base's
  // factor (support_system.h; as the certificate solves the models), else with a factorisation
  // of its own (as the fit's judgements do: probe_evaluation.h, ToolSolves).
  void AddTool(std::size_t base, ProbeFamily family, const std::vector<int>& nodes,
               const Vector& direction, bool held_out_only) {
    Support support = bank_.supports[base];
    support.user = false;
    support.tool_nodes = nodes;
    support.base = static_cast<int>(base);
    for (int node : nodes) support.constrained[static_cast<std::size_t>(node)] = true;
    support.description =
        fmt::format("{} at node {} on {}", family == ProbeFamily::kPush ? "push" : "grasp",
                    nodes[0], bank_.supports[base].description);
    SupportSystem system(d_, support.constrained, held_out_only ? &systems_[base] : nullptr);
    if (!system.Factorize(reference_stiffness_)) return;
    Probe probe;
    probe.family = family;
    probe.force = Vector::Zero(d_ * n_);
    probe.prescribed = Vector::Zero(d_ * n_);
    for (int node : nodes) probe.prescribed.segment(d_ * node, d_) = bank_.amplitude * direction;
    probe.reference = system.Displacement(probe.force, probe.prescribed);
    probe.support = static_cast<int>(bank_.supports.size());
    bank_.supports.push_back(std::move(support));
    systems_.push_back(std::move(system));
    bank_.probes.push_back(std::move(probe));
  }

  const Problem& problem_;
  const Scene& scene_;
  const SparseMatrix& reference_stiffness_;
  const ProbeOptions& options_;
  const int d_;
  const int n_;
  RandomStream random_;
  const Surface surface_;
  ProbeBank bank_;
  std::vector<bool> held_;  // per probe of bank_: held out
  // Per support of the bank (a deque: a tool load's system points to its base's).
  std::deque<SupportSystem> systems_;
  std::vector<int> support_of_free_set_;
};

}  // namespace

ProbeBanks MakeProbeBanks(const Problem& problem, const SparseMatrix& reference_stiffness,
                          const ProbeOptions& options) {
  options.Validate();
  const int user_supports = static_cast<int>(problem.free_sets().size());
  if (options.count > 0 && options.count < MinimumProbeCount(user_supports, options)) {
    throw std::invalid_argument(fmt::format(
        "ProbeOptions.count: {} probes are too few for {} supports ({} of the load cases, {} "
        "drawn): at least {} ({} per family on each support: one fitted, one choosing, one "
        "held out)",
        options.count, user_supports + options.extra_supports, user_supports,
        options.extra_supports, MinimumProbeCount(user_supports, options), kGroupMinimum));
  }
  BankBuilder builder(problem, reference_stiffness, options);
  builder.AddUserSupports();
  builder.AddNamedCases();
  builder.DrawSupports();
  builder.AddGeneratedProbes();
  builder.AddToolProbes();
  auto [fit, held_out] = builder.Finish();
  return {std::move(fit), HeldOutProbes(std::move(held_out))};
}

void AddSoftModeProbe(ProbeBank& bank, int support, const Vector& shape,
                      const SparseMatrix& reference_stiffness, int dimension) {
  const double largest = LargestNodalDisplacement(dimension, shape);
  if (!(largest > 0.0)) return;
  Probe probe;
  probe.family = ProbeFamily::kMode;
  probe.role = ProbeRole::kFit;
  probe.support = support;
  probe.reference = shape * (bank.amplitude / largest);
  probe.force = reference_stiffness * probe.reference;
  // The reactions on the held nodes are the support's, not the load's.
  const std::vector<bool>& held = bank.supports[static_cast<std::size_t>(support)].constrained;
  for (std::size_t node = 0; node < held.size(); ++node) {
    if (held[node])
      probe.force.segment(dimension * static_cast<Eigen::Index>(node), dimension).setZero();
  }
  probe.reference_norm2 = probe.reference.squaredNorm();
  bank.probes.push_back(std::move(probe));
}

Surface AnySurface(const Scene& scene) {
  if (scene.reference.kind == Reference::Kind::kFem) return FemSurface(scene);
  Surface s;
  s.nodes.reserve(static_cast<std::size_t>(scene.node_count()));
  for (int node = 0; node < scene.node_count(); ++node) s.nodes.push_back(node);
  s.normal = Vector::Zero(scene.rest.size());
  return s;
}

}  // namespace springfit::response
