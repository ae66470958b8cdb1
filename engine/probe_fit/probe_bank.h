// The probe bank: load cases springfit generates from the reference itself, so that an
// identification sees the whole response and is judged on loads it was not fitted to
// (docs/ARCHITECTURE.md, "The probe fit").
//
// Supports: the user's (each distinct set of nodes the named load cases hold) and
// `extra_supports` more, each a patch of boundary nodes around a random boundary node (the
// nearest boundary nodes to it, `support_fraction` of the boundary), kept when the reference
// is held by it (its rest stiffness is positive definite on the free nodes).
// Families, on every support (no load on a held node):
//   point  a force on one boundary node: half of them along the inward normal (a tool pushing
//          the surface in), half in a uniformly random direction;
//   patch  a force spread evenly on a boundary node and its nearest boundary neighbours (3 to
//          8 nodes in all), in a random direction: a grasp, a contact;
//   body   a uniform body force (lumped by element volume) along each axis and along random
//          directions: gravity, inertia;
//   push   a tool pushing a boundary node in along its inward normal to a depth (an imposed
//          displacement, not a force: a tool moves to a depth); FEM references only. Each push
//          is a support of its own, the base support with the pushed node held at its depth
//          (Support::tool_nodes), so the shape the body takes around a tool is fitted, chosen
//          on and certified like every other family's;
//   grasp  a tool holding a boundary node and its two nearest boundary neighbours and moving
//          them in together along the first's inward normal (a grasper, a spatula); as push;
//   named  the user's load cases (in the fit with the stated weight `named_weight`).
// Every generated probe is scaled so that its largest nodal displacement in the reference equals
// the named cases' median largest displacement (the loads a simulator applies are of that
// size; the linear response does not care, a nonlinear one does); a tool moves its nodes by
// that size (its depth).
// Roles: each (support, family) group of generated probes is shuffled and split into a part
// that is fitted, a part that chooses among fitted models (the regularisation, the point of
// the sparsity path), and a held-out part that no fit and no choice ever sees, on which the
// certificate reports. The named cases are all fitted. The held-out part is a type of its own
// (HeldOutProbes), which gives its probes to the certificate alone (docs/ARCHITECTURE.md,
// "Probes by role"): a fit or a choice cannot be handed them, the compiler refuses it. Every
// group has at least three probes (one per role): a request for fewer probes than that needs
// is refused before any work (MinimumProbeCount).
//
// Boundary: for an FEM reference, the nodes of the facets (edges in 2D, faces in 3D) that belong
// to one element only, with the outward normal summed over them; for an MSS reference (no
// surface), every node, with no normal (point loads then take random directions).
//
// The same problem, options and seed give the same bank.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "engine/api/probe_fit_report.h"
#include "engine/api/problem.h"
#include "engine/problem/rest_stiffness.h"

namespace springfit::response {

// The roles of the probes in a ProbeBank; the held-out ones are in HeldOutProbes.
enum class ProbeRole { kFit, kSelect };

struct ProbeOptions {
  // Generated probes in all, spread over the supports and families (at least 3 per family on
  // each support, so that each role has one); 0: automatic (per support, min(boundary nodes,
  // 24) point loads, 12 patches and d + 2 body forces). At least MinimumProbeCount.
  int count = 0;
  // Supports drawn from the boundary beside the user's, >= 0.
  int extra_supports = 3;
  // Tool pushes (family push) and grasps (family grasp) per support, user and drawn, on
  // boundary nodes evenly spread over its free boundary: each 0 (none), or at least 3 (one per
  // role). Each is a support of its own, so each fitted or choosing one costs one more
  // factorisation per fit step. Not counted in `count`. FEM references only (an MSS has no
  // surface to push).
  int pushes = 8;
  int grasps = 6;
  // Of the boundary's nodes held by a drawn support, in (0, 0.5].
  double support_fraction = 0.15;
  // Of each group of generated probes: chosen on, and held out; both in (0, 0.5].
  double select_fraction = 0.2;
  double held_out_fraction = 0.25;
  // The named cases' share of the fitted objective (the generated families share the rest
  // equally), in [0, 1).
  double named_weight = 0.25;
  // The share of the soft-mode probes (family kMode), when the fit adds any: the smallest share
  // that lifted the kidney's soft modes with its held-out errors unchanged; larger ones lifted
  // them further but worsened the independent evaluator's pushed-node tail (bench/RESULTS.md,
  // "Fitting the response"). In [0, 1), with named_weight + soft_mode_weight < 1.
  double soft_mode_weight = 0.01;
  // The tool loads' share of the fitted objective (split equally between the push and grasp
  // families the bank has), in [0, 1), with named_weight + soft_mode_weight + tool_weight < 1.
  // On the 2D examples this share lowered the held-out pushes' E and kept the other families'
  // (bench/RESULTS.md, "Round seven").
  double tool_weight = 0.1;
  // In 3D the tool loads are held out (judged by the certificate, neither fitted nor chosen on)
  // unless this is set: an imposed point displacement's shape in a tetrahedral mesh is set by
  // the few elements at the node (its energy vanishes as the mesh refines), which no spring
  // model on fem-block-3d came near, fitted or not, while the pushes' supports (one
  // factorisation each per fit step) made the fit longer and every other family worse
  // (bench/RESULTS.md, "Round seven").
  bool fit_tools_in_3d = false;
  // Grasps are held out (judged by the certificate) unless this is set. Fitted beside the
  // pushes (the tool share split between them) they made the kidney's named cases worse, the
  // fine kidney's fit longer and its held-out pushes no better (bench/RESULTS.md, "Round
  // seven"): the pushes already carry the shape around a tool.
  bool fit_grasps = false;
  std::uint64_t seed = 1;

  // Throws std::invalid_argument naming the field, its value and the rule.
  void Validate(const std::string& owner = "ProbeOptions") const;
};

// The reference's boundary (above): its nodes and their outward unit normals.
struct Surface {
  std::vector<int> nodes;  // ascending
  Vector normal;           // flat d*n, outward unit normals (zero off the surface)
};
Surface AnySurface(const Scene& scene);

struct Support {
  std::vector<bool> constrained;  // per node
  bool user = false;              // held by some named load case
  // A tool load's support (families push and grasp): the nodes the tool holds at their depth,
  // besides the base support's nodes; empty for every other support.
  std::vector<int> tool_nodes;
  // A tool load's base support (index into the bank's supports: the one the tool pushes on,
  // which holds its other nodes); -1 for every other support. Its systems solve through the
  // base's factor (support_system.h).
  int base = -1;
  bool tool() const { return !tool_nodes.empty(); }
  std::string description;  // "load case 'stretch'", "boundary patch around node 17"
};

struct Probe {
  ProbeFamily family = ProbeFamily::kPoint;
  ProbeRole role = ProbeRole::kFit;
  int support = 0;      // index into ProbeBank::supports
  int named_case = -1;  // kNamed: the problem's load case
  Vector force;         // flat d*n
  // Flat d*n: the prescribed displacements of the named cases and the tool loads; empty for
  // the other generated probes (none: a flat zero vector per probe was a third of a large
  // bank's memory).
  Vector prescribed;
  Vector reference;              // the reference's rest-linear displacement under it, flat d*n
  double reference_norm2 = 0.0;  // |u| over the support's free nodes, squared
};

// The probes a fit may see: fitted and choosing ones (the named cases among the fitted).
struct ProbeBank {
  std::vector<Support> supports;
  std::vector<Probe> probes;
  std::vector<int> boundary;  // the boundary's nodes, ascending
  double amplitude = 0.0;     // the generated probes' largest nodal displacement
};

struct ProbeBanks;
class Certifier;  // generalization.h

// The held-out probes: loads no fit and no choice ever sees. Their probes are readable by the
// certificate (Certifier) alone; everything else sees how many there are.
class HeldOutProbes {
 public:
  HeldOutProbes() = default;
  int size() const { return static_cast<int>(bank_.probes.size()); }

 private:
  friend class Certifier;
  friend ProbeBanks MakeProbeBanks(const Problem& problem, const SparseMatrix& reference_stiffness,
                                   const ProbeOptions& options);
  explicit HeldOutProbes(ProbeBank bank) : bank_(std::move(bank)) {}
  ProbeBank bank_;  // the same supports as the fit's bank; its probes' roles mean nothing
};

struct ProbeBanks {
  ProbeBank fit;  // fitted and choosing probes, with the named cases
  HeldOutProbes held_out;
};

// The fewest generated probes an explicit ProbeOptions::count may ask for on a problem with
// `user_supports` distinct supports among its load cases: 3 per family (one per role) on each
// user support and each drawn one.
int MinimumProbeCount(int user_supports, const ProbeOptions& options);

// The tool loads (pushes and grasps) MakeProbeBanks adds at most on a problem with
// `user_supports` distinct supports among its load cases.
int MaximumToolCount(int user_supports, const ProbeOptions& options);

// The bytes a bank of `probes` probes on `nodes` nodes in `dimension` holds (each probe's force
// and reference displacement, flat d*n), a lower bound of a probe fit's memory.
double ProbeBankBytes(long long probes, int nodes, int dimension);

// Adds a fitted probe of family kMode on `support`: the load K_ref v under which the reference
// moves by `shape` = v (flat d*n, 0 on the support's nodes), scaled to the bank's amplitude.
void AddSoftModeProbe(ProbeBank& bank, int support, const Vector& shape,
                      const SparseMatrix& reference_stiffness, int dimension);

// Precondition: the problem's reference is FEM or MSS; `reference_stiffness` is its
// ReferenceRestStiffness. Throws std::invalid_argument for invalid options (a count below
// MinimumProbeCount among them), and InputError when no user support holds the reference (a
// load case that leaves it free to move).
ProbeBanks MakeProbeBanks(const Problem& problem, const SparseMatrix& reference_stiffness,
                          const ProbeOptions& options);

}  // namespace springfit::response
