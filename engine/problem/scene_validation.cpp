#include "engine/api/scene.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <string>

#include "engine/fem/fem_validation.h"
#include "engine/model/point_index.h"
#include "engine/runtime/input_error.h"
#include "engine/runtime/number_text.h"

namespace springfit {
namespace {

// Two nodes closer than this fraction of the scene's extent are at the same position.
constexpr double kCoincidentTolerance = 1e-9;

std::string Index(const std::string& path, std::size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

// Every number of a scene is at most this in magnitude, and a stiffness at least its inverse:
// energies and Hessians multiply up to four of them (k l^2, k^2 l^2 in a force balance),
// which beyond it would overflow or underflow double precision and turn into a penalty error
// on a job that says it succeeded.
constexpr double kMaxMagnitude = 1e100;

std::string MagnitudeText(double v) {
  return NumberText(v, 3);
}

// A coordinate, force or displacement: finite and at most kMaxMagnitude.
void CheckMagnitude(double v, const std::string& path) {
  if (!std::isfinite(v)) throw InputError(path, "not a finite number");
  if (std::abs(v) > kMaxMagnitude) {
    throw InputError(path, MagnitudeText(v) +
                               " is beyond 1e+100 in magnitude: rescale the "
                               "scene's units (springfit computes in double "
                               "precision)");
  }
}

// A stiffness or modulus: finite, > 0, within [1e-100, 1e100].
void CheckPositive(double v, const std::string& path, const char* what) {
  if (!std::isfinite(v)) throw InputError(path, "not a finite number");
  if (v == 0.0) {
    throw InputError(path, std::string(what) +
                               " must be > 0, got 0 (a number smaller than about 1e-308, such "
                               "as 1e-400, reads as 0)");
  }
  if (!(v > 0.0))
    throw InputError(path, std::string(what) + " must be > 0, got " + MagnitudeText(v));
  if (v < 1.0 / kMaxMagnitude || v > kMaxMagnitude) {
    throw InputError(path, std::string(what) + " " + MagnitudeText(v) +
                               " is outside [1e-100, 1e+100]: rescale the scene's units "
                               "(springfit computes in double precision)");
  }
}

void CheckNode(const Scene& s, int node, const std::string& path) {
  if (node < 0 || node >= s.node_count()) {
    throw InputError(path, "node index " + std::to_string(node) + " out of range [0, " +
                               std::to_string(s.node_count()) + ")");
  }
}

void CheckVector(const Scene& s, const Vector& v, const std::string& path) {
  if (v.size() != s.dimension) {
    throw InputError(path, "expected " + std::to_string(s.dimension) +
                               " components (the scene is " + std::to_string(s.dimension) +
                               "D), got " + std::to_string(v.size()));
  }
  for (Eigen::Index a = 0; a < v.size(); ++a) {
    CheckMagnitude(v[a], Index(path, a));
  }
}

void CheckPairs(const Scene& s, const std::vector<NodePair>& pairs, const std::string& path,
                const char* what) {
  std::set<NodePair> seen;
  for (std::size_t m = 0; m < pairs.size(); ++m) {
    const std::string p = Index(path, m);
    CheckNode(s, pairs[m].first, p + "[0]");
    CheckNode(s, pairs[m].second, p + "[1]");
    if (pairs[m].first == pairs[m].second) {
      throw InputError(p, std::string("self ") + what + ": both ends are node " +
                              std::to_string(pairs[m].first));
    }
    const NodePair key{std::min(pairs[m].first, pairs[m].second),
                       std::max(pairs[m].first, pairs[m].second)};
    if (!seen.insert(key).second) {
      throw InputError(p, std::string("duplicate ") + what + " (" + std::to_string(key.first) +
                              ", " + std::to_string(key.second) + ")");
    }
  }
}

double Extent(const Scene& s) {
  return s.Bounds().Diagonal();
}

// A 3D scene whose nodes all lie in one plane: springs (and a flat mesh) have no stiffness
// across it, so every model, the reference's too, is a mechanism there. Said here, at the
// nodes, rather than later as a mechanism or a rigid-motion error. O(n): the plane is the
// centred nodes' direction of least spread.
void CheckNotPlanar(const Scene& s) {
  const int n = s.node_count();
  if (n < 3) return;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) centre += s.rest.segment<3>(3 * i);
  centre /= n;
  Eigen::Matrix3d spread = Eigen::Matrix3d::Zero();
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d x = s.rest.segment<3>(3 * i) - centre;
    spread += x * x.transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(spread);
  const Eigen::Vector3d normal = eigen.eigenvectors().col(0);  // least spread
  double off = 0.0;
  bool flat_z = true;
  for (int i = 0; i < n; ++i) {
    off = std::max(off, std::abs(normal.dot(s.rest.segment<3>(3 * i) - centre)));
    flat_z = flat_z && s.rest[3 * i + 2] == 0.0;
  }
  if (off > kCoincidentTolerance * Extent(s)) return;
  throw InputError("nodes",
                   "all " + std::to_string(n) +
                       " nodes lie in one plane: a 3D model of them has no stiffness across it "
                       "(every topology is a mechanism there)" +
                       (flat_z ? std::string("; for a plane model write each node as [x, y] "
                                             "(2D), without the z = 0")
                               : std::string("")));
}

void CheckNodes(const Scene& s) {
  if (s.dimension != 2 && s.dimension != 3) {
    throw InputError("nodes", "dimension must be 2 or 3, got " + std::to_string(s.dimension));
  }
  if (s.node_count() < 2) throw InputError("nodes", "a scene needs at least two nodes");
  for (int i = 0; i < s.rest.size(); ++i)
    CheckMagnitude(s.rest[i], Index(Index("nodes", i / s.dimension), i % s.dimension));
  // A k-d tree finds each node's coincident neighbours in O(log n), whatever the layout (a
  // sweep along one axis was quadratic for nodes on a line across it).
  const int d = s.dimension;
  const double tol = kCoincidentTolerance * Extent(s);
  const PointIndex index(s.rest, d);
  for (int i = 0; i < s.node_count(); ++i) {
    for (const int j : index.WithinRadius(index.Point(i), tol)) {
      if (j >= i) break;  // ascending: the earlier node it coincides with comes first
      throw InputError(Index("nodes", i),
                       "at the same position as nodes[" + std::to_string(j) + "]");
    }
  }
  if (d == 3) CheckNotPlanar(s);
}

void CheckCandidates(const Scene& s) {
  const CandidateSpec& c = s.candidates;
  switch (c.kind) {
    case CandidateSpec::Kind::kGrid:
      if (!c.spacing.empty()) {
        if (static_cast<int>(c.spacing.size()) != s.dimension) {
          throw InputError("candidates.spacing",
                           "expected one step per axis (" + std::to_string(s.dimension) + ")");
        }
        for (std::size_t a = 0; a < c.spacing.size(); ++a) {
          if (!(c.spacing[a] > 0.0) || !std::isfinite(c.spacing[a])) {
            throw InputError(Index("candidates.spacing", a), "must be a finite number > 0");
          }
        }
      }
      break;
    case CandidateSpec::Kind::kNearest:
      if (c.k < 1) throw InputError("candidates.k", "must be >= 1, got " + std::to_string(c.k));
      break;
    case CandidateSpec::Kind::kMesh:
      if (c.k < 0) throw InputError("candidates.k", "must be >= 0, got " + std::to_string(c.k));
      if (s.reference.kind != Reference::Kind::kFem) {
        throw InputError("candidates.type",
                         "mesh candidates are the edges of a reference of type fem");
      }
      break;
    case CandidateSpec::Kind::kRadius:
      if (!(c.radius > 0.0) || !std::isfinite(c.radius)) {
        throw InputError("candidates.radius", "must be a finite number > 0");
      }
      break;
    case CandidateSpec::Kind::kPairs:
      if (c.pairs.empty()) throw InputError("candidates.pairs", "must not be empty");
      CheckPairs(s, c.pairs, "candidates.pairs", "pair");
      break;
  }
}

void CheckReference(const Scene& s) {
  const Reference& r = s.reference;
  if (r.kind == Reference::Kind::kMss) {
    if (r.springs.empty()) throw InputError("reference.springs", "must not be empty");
    CheckPairs(s, r.springs, "reference.springs", "spring");
    if (r.stiffness.size() != 1 && r.stiffness.size() != r.springs.size()) {
      throw InputError("reference.stiffness", "expected one value or one per spring (" +
                                                  std::to_string(r.springs.size()) + "), got " +
                                                  std::to_string(r.stiffness.size()));
    }
    for (std::size_t m = 0; m < r.stiffness.size(); ++m) {
      const std::string p = r.stiffness.size() == 1 ? std::string("reference.stiffness")
                                                    : Index("reference.stiffness", m);
      CheckPositive(r.stiffness[m], p, "stiffness");
    }
    return;
  }
  if (r.kind == Reference::Kind::kFem) {
    fem::ValidateFemReference(s);
    return;
  }
  if (r.positions.size() != s.load_cases.size()) {
    throw InputError("reference.positions", "expected one configuration per load case (" +
                                                std::to_string(s.load_cases.size()) + "), got " +
                                                std::to_string(r.positions.size()));
  }
  for (std::size_t k = 0; k < r.positions.size(); ++k) {
    const std::string p = Index("reference.positions", k);
    if (r.positions[k].size() != s.rest.size()) {
      throw InputError(p, "expected " + std::to_string(s.node_count()) + " nodes, got " +
                              std::to_string(r.positions[k].size() / s.dimension));
    }
    for (Eigen::Index i = 0; i < r.positions[k].size(); ++i)
      CheckMagnitude(r.positions[k][i], Index(Index(p, i / s.dimension), i % s.dimension));
  }
}

void CheckRigidMotion(const Scene& s, const std::vector<int>& constrained, const std::string& path,
                      const std::string& what) {
  const int d = s.dimension;
  const char* rule = d == 2
                         ? "at least two constrained (fixed or displaced) nodes"
                         : "at least three constrained (fixed or displaced) nodes not on one line";
  if (static_cast<int>(constrained.size()) < d) {
    throw InputError(path, what + "a load case needs " + rule);
  }
  if (d == 2) return;
  const double extent = Extent(s);
  const Eigen::Vector3d a = s.rest.segment<3>(3 * constrained[0]);
  const Eigen::Vector3d b = s.rest.segment<3>(3 * constrained[1]);
  for (std::size_t m = 2; m < constrained.size(); ++m) {
    const Eigen::Vector3d c = s.rest.segment<3>(3 * constrained[m]);
    if ((b - a).cross(c - a).norm() > 1e-9 * extent * extent) return;
  }
  throw InputError(path, what + "a load case needs " + rule);
}

void CheckLoads(const Scene& s, const std::vector<NodalLoad>& loads, const std::string& path,
                const char* value_name, std::vector<int>& role, int role_id, bool& nonzero) {
  for (std::size_t m = 0; m < loads.size(); ++m) {
    const std::string p = Index(path, m);
    const NodalLoad& load = loads[m];
    if (load.nodes.empty()) throw InputError(p + ".nodes", "must not be empty");
    for (std::size_t q = 0; q < load.nodes.size(); ++q) {
      // A node of a named set: the load the user wrote is named, then the set's entry.
      const std::string np = load.single        ? p + ".node"
                             : load.set.empty() ? Index(p + ".nodes", q)
                                                : p + ".nodes ('" + load.set + "', " +
                                                      Index("node_sets." + load.set, q) + ")";
      CheckNode(s, load.nodes[q], np);
      int& r = role[load.nodes[q]];
      if (role_id == 2) {  // a force
        if (r == 0 || r == 1) {
          throw InputError(np, "node " + std::to_string(load.nodes[q]) +
                                   " is constrained in this load case; forces go on free nodes "
                                   "(a support and a load on one node set: load another set)");
        }
      } else {
        if (r == 0 || r == 1) {
          throw InputError(np, "node " + std::to_string(load.nodes[q]) +
                                   " is already fixed or displaced in this load case");
        }
        r = role_id;
      }
    }
    CheckVector(s, load.value, p + "." + value_name);
    if (load.value.squaredNorm() > 0.0) nonzero = true;
  }
}

void CheckLoadCases(const Scene& s) {
  if (s.load_cases.empty()) throw InputError("load_cases", "a scene needs at least one load case");
  for (std::size_t k = 0; k < s.load_cases.size(); ++k) {
    const LoadCase& lc = s.load_cases[k];
    const std::string p = Index("load_cases", k);
    // role: -1 free, 0 fixed, 1 displaced
    std::vector<int> role(s.node_count(), -1);
    for (std::size_t m = 0; m < lc.fixed.size(); ++m) {
      // Nodes given by a set's name are named where the set lists them.
      const std::string fp =
          lc.fixed_set.empty() ? Index(p + ".fixed", m) : Index("node_sets." + lc.fixed_set, m);
      CheckNode(s, lc.fixed[m], fp);
      if (role[lc.fixed[m]] == 0) {
        throw InputError(fp, "node " + std::to_string(lc.fixed[m]) + " is listed twice");
      }
      role[lc.fixed[m]] = 0;
    }
    bool nonzero = false;
    CheckLoads(s, lc.displacements, p + ".displacements", "displacement", role, 1, nonzero);
    CheckLoads(s, lc.forces, p + ".forces", "force", role, 2, nonzero);
    for (std::size_t m = 0; m < lc.tractions.size(); ++m) {
      const std::string tp = Index(p + ".tractions", m);
      if (s.reference.kind != Reference::Kind::kFem) {
        throw InputError(tp, "a traction needs a mesh: a reference of type fem");
      }
      const Traction& t = lc.tractions[m];
      CheckVector(s, t.value,
                  tp + (t.total            ? ".total"
                        : s.dimension == 2 ? ".per_length"
                                           : ".per_area"));
      if (t.value.squaredNorm() > 0.0) nonzero = true;
    }
    if (!nonzero) {
      throw InputError(
          p, "applies no load: it needs a nonzero force, traction or prescribed displacement");
    }
    std::vector<int> constrained;
    for (int i = 0; i < s.node_count(); ++i) {
      if (role[i] == 0 || role[i] == 1) constrained.push_back(i);
    }
    // The case's name beside its index (what the user wrote in the loads file), and the
    // fields that hold it.
    CheckRigidMotion(s, constrained, p,
                     (lc.name.empty() ? std::string() : "case '" + lc.name + "': ") +
                         "its `fixed` and `displacements` leave rigid motion free: ");
    if (static_cast<int>(constrained.size()) == s.node_count()) {
      throw InputError(p, "every node is constrained: nothing is left to deform");
    }
  }
}

// The search settings that apply to the strategy the scene runs: a setting that would do
// nothing is refused, naming the one that acts.
void CheckSearchApplies(const Scene& scene) {
  const SearchSettings& s = scene.search;
  // Strategy default is continuous on an FEM reference, direct where it identifies stiffness,
  // hybrid otherwise (ResolvedStrategy).
  const Strategy runs = ResolvedStrategy(s.strategy, scene);
  const bool continuous = runs == Strategy::kContinuous;
  if (s.identify == Identify::kTopologyAndStiffness && runs != Strategy::kDirect && !continuous) {
    // The genetic strategies compare topologies whose springs all have the training
    // stiffness; they have nothing to say about each spring's stiffness.
    throw InputError(
        "search.identify",
        "topology_and_stiffness needs strategy direct, continuous or default (paper and hybrid "
        "identify the topology with the one training stiffness)");
  }
  if (s.identify == Identify::kTopology && continuous) {
    throw InputError("search.identify",
                     "strategy continuous (default on an FEM reference) identifies each spring's "
                     "stiffness: use topology_and_stiffness, or strategy hybrid for the topology "
                     "alone");
  }
  if ((s.max_springs || s.target_error) && !continuous) {
    throw InputError(s.max_springs ? "search.max_springs" : "search.target_error",
                     "chooses a point of the sparsity path: it needs strategy continuous (or "
                     "default on an FEM reference)");
  }
  if (s.regularization && !continuous) {
    throw InputError("search.regularization",
                     "regularises the continuous fit: it needs strategy continuous (or default on "
                     "an FEM reference)");
  }
  if (s.probes && *s.probes > 0 && !continuous) {
    throw InputError("search.probes",
                     "sets the probe loads of the continuous fit: it needs strategy continuous "
                     "(or default on an FEM reference)");
  }
  // The genetic search's settings, where no genetic search runs (issue 33: an option that
  // does nothing is refused, naming the one that acts).
  if (runs == Strategy::kContinuous || runs == Strategy::kDirect) {
    const std::string ran = std::string(runs == Strategy::kContinuous ? "continuous" : "direct") +
                            (s.strategy == Strategy::kDefault ? " (default for this scene)" : "");
    const auto refuse = [&](const char* field, const char* flag) {
      throw InputError(std::string("search.") + field,
                       std::string("is read by the genetic search only (--") + flag +
                           "), and this scene runs strategy " + ran +
                           (runs == Strategy::kContinuous
                                ? ": the fit's stopping choice is search.target_error "
                                  "(--target-error E, the relative RMS error), its size "
                                  "search.max_springs (--max-springs)"
                                : "") +
                           "; leave it out, or run strategy paper or hybrid");
    };
    if (s.population) refuse("population", "population");
    if (s.crossover_probability) refuse("crossover_probability", "crossover");
    if (s.mutation_probability) refuse("mutation_probability", "mutation");
    if (s.stall_generations) refuse("stall_generations", "stall");
    // (Direct reads the target: a model above it is not_reproduced.)
    if (runs == Strategy::kContinuous && s.target_normalized_error > 0.0)
      refuse("target_normalized_error", "target");
  }
  if (s.probes && *s.probes > 0 && scene.reference.kind == Reference::Kind::kPositions) {
    throw InputError("search.probes",
                     "a positions reference (measurements) cannot be probed: its model is "
                     "fitted to its load cases and judged by cross-validation over them; use "
                     "\"none\" or leave it out");
  }
}

// The search settings' values within their documented ranges (and the spread bound where the
// fit to probes runs).
void CheckSearchRanges(const Scene& scene) {
  const SearchSettings& s = scene.search;
  const bool continuous = ResolvedStrategy(s.strategy, scene) == Strategy::kContinuous;
  if (s.regularization && !s.regularization->automatic &&
      !(s.regularization->strength >= 0.0 && std::isfinite(s.regularization->strength))) {
    throw InputError("search.regularization", "must be \"auto\" or a finite number >= 0");
  }
  if (s.max_springs && *s.max_springs < 1) {
    throw InputError("search.max_springs", "must be >= 1, got " + std::to_string(*s.max_springs));
  }
  if (s.target_error && !(*s.target_error > 0.0 && std::isfinite(*s.target_error))) {
    throw InputError("search.target_error", "must be a finite number > 0");
  }
  if (s.max_spread && !(*s.max_spread > 1.0 && std::isfinite(*s.max_spread))) {
    throw InputError("search.max_spread",
                     "must be a finite number > 1 (the largest stiffness over the smallest)");
  }
  if (s.max_spread && (!continuous || scene.reference.kind == Reference::Kind::kPositions ||
                       (s.probes && *s.probes == 0) || s.target_error)) {
    throw InputError("search.max_spread",
                     "bounds the stiffness of the fit to probes: it needs strategy continuous (or "
                     "default on an FEM reference) on an FEM or MSS reference, with probes (not "
                     "\"none\") and no target error");
  }
  if (s.load_size && !(*s.load_size > 0.0 && std::isfinite(*s.load_size))) {
    throw InputError("search.load_size",
                     "must be a finite number > 0 (the largest nodal displacement the "
                     "simulator's loads cause, in the scene's length)");
  }
  if (s.load_size && (!continuous || scene.reference.kind == Reference::Kind::kPositions ||
                      (s.probes && *s.probes == 0) || s.target_error)) {
    throw InputError("search.load_size",
                     "sets the size the fit to probes is judged and fitted at: it needs "
                     "strategy continuous (or default on an FEM reference) on an FEM or MSS "
                     "reference, with probes (not \"none\") and no target error");
  }
  if (s.population && *s.population < 2) {
    throw InputError("search.population", "must be >= 2, got " + std::to_string(*s.population));
  }
  if (s.crossover_probability &&
      !(*s.crossover_probability >= 0.0 && *s.crossover_probability <= 1.0)) {
    throw InputError("search.crossover_probability", "must be in [0, 1]");
  }
  if (s.mutation_probability &&
      !(*s.mutation_probability >= 0.0 && *s.mutation_probability <= 1.0)) {
    throw InputError("search.mutation_probability", "must be in [0, 1]");
  }
  if (s.max_generations < 1) {
    throw InputError("search.max_generations",
                     "must be >= 1, got " + std::to_string(s.max_generations));
  }
  if (s.max_seconds && !(*s.max_seconds > 0.0 && std::isfinite(*s.max_seconds))) {
    throw InputError("search.max_seconds", "must be a finite number > 0");
  }
  if (s.stall_generations && *s.stall_generations < 0) {
    throw InputError("search.stall_generations",
                     "must be >= 0 (0 = never), got " + std::to_string(*s.stall_generations));
  }
  if (!(s.target_normalized_error >= 0.0) || !std::isfinite(s.target_normalized_error)) {
    throw InputError("search.target_normalized_error", "must be a finite number >= 0");
  }
}

void CheckSearch(const Scene& scene) {
  CheckSearchApplies(scene);
  CheckSearchRanges(scene);
}

void CheckNodeSets(const Scene& s) {
  for (const auto& [name, nodes] : s.node_sets) {
    for (std::size_t q = 0; q < nodes.size(); ++q)
      CheckNode(s, nodes[q], Index("node_sets." + name, q));
  }
}

}  // namespace

void ValidateScene(const Scene& s) {
  CheckNodes(s);
  CheckCandidates(s);
  CheckNodeSets(s);
  CheckLoadCases(s);
  CheckReference(s);
  if (s.training_stiffness) {
    CheckPositive(*s.training_stiffness, "stiffness", "stiffness");
  }
  CheckSearch(s);
  if (s.units) DeriveUnits(*s.units);
}

}  // namespace springfit
