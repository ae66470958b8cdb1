// The engine's public surface (engine/api/: what proto/, io/, figures/, server/ and client/ may
// include, and the vocabulary the engine's rooms share; tests/include_graph_check.py enforces
// it). A scene: everything an identification needs, as plain validated data.
//
// The nodes' rest positions, the candidate springs (the node pairs that may carry a spring:
// one gene each), the reference model whose deformation the training model must reproduce,
// the load cases, the training model's stiffness and the search settings. A Scene is what the
// JSON scene format (proto/SCENE.md) describes; proto/scene_codec.h reads and validates it.
// Derived quantities (candidate list, reference equilibria, scales) live in Problem
// (engine/api/problem.h), which is built from a Scene.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "engine/linalg/linalg.h"

namespace springfit {

// An unordered node pair, stored with first < second.
struct NodePair {
  int first = 0;
  int second = 0;
  friend bool operator==(const NodePair&, const NodePair&) = default;
  friend auto operator<=>(const NodePair&, const NodePair&) = default;
};

// How the candidate springs are generated from the nodes.
struct CandidateSpec {
  enum class Kind {
    kGrid,     // lattice neighbours: Chebyshev distance of one lattice step (8 in 2D, 26 in 3D)
    kNearest,  // pair (i,j) if j is among the k nearest neighbours of i, or i among j's
    kRadius,   // every pair at rest distance <= radius
    kPairs,    // an explicit list
    kMesh,     // the edges of an FEM reference's elements, plus the k nearest neighbours (k >= 0)
  };
  Kind kind = Kind::kGrid;
  // kGrid: lattice step per axis; empty = inferred (the smallest difference between the nodes'
  // coordinates along that axis above 1e-6 of the axis's range).
  std::vector<double> spacing;
  int k = 8;                    // kNearest (>= 1); kMesh (>= 0, default 0)
  double radius = 0.0;          // kRadius
  std::vector<NodePair> pairs;  // kPairs
};

// One force or prescribed displacement applied alike to one or more nodes; `value` has the
// scene's dimension. `single` records that the scene named one "node" rather than a "nodes"
// list, so that writing the scene back keeps its form.
// `set` names the node set the nodes were given as (written back as that name), or is empty.
struct NodalLoad {
  std::vector<int> nodes;
  Vector value;
  bool single = false;
  std::string set;
};

// A distributed load on the boundary of an FEM reference's mesh: a constant traction on the
// boundary edges (2D) or faces (3D) whose nodes all belong to the node set `on`, turned into
// consistent nodal forces when the scene is prepared (engine/fem/traction.h).
struct Traction {
  std::string on;          // a node set's name
  std::vector<int> nodes;  // that set's nodes (resolved by the reader)
  Vector value;            // d components
  // true: `value` is the total force over those edges or faces; false: force per unit length
  // of edge (2D, through the whole thickness) or per unit area of face (3D).
  bool total = true;
};

struct LoadCase {
  std::string name;
  std::vector<int> fixed;                // nodes held at their rest position
  std::string fixed_set;                 // the node set `fixed` was given as, or empty
  std::vector<NodalLoad> forces;         // external forces on free nodes (they add up)
  std::vector<NodalLoad> displacements;  // nodes moved by a prescribed displacement
  std::vector<Traction> tractions;       // distributed loads (FEM references only)
};

// The constitutive law of a finite-element reference (engine/fem/material_law.h has the
// energies).
enum class MaterialModel { kLinear, kStVenantKirchhoff, kNeoHookean };

struct Material {
  MaterialModel model = MaterialModel::kLinear;
  double young = 0.0;    // Young's modulus, > 0 (force per area)
  double poisson = 0.0;  // Poisson's ratio, in (-1, 0.5)
  // Mass per volume (> 0), for the masses an exported model carries (io/spring_model.h); the
  // static identification does not use it. In the scene's units: mass = force / (length /
  // time^2), e.g. tonnes per mm^3 in mm and N.
  std::optional<double> density = std::nullopt;
  friend bool operator==(const Material&, const Material&) = default;
};

// A 2D finite-element model is a thin sheet (plane stress) or a slice of a long body (plane
// strain).
enum class PlaneMode { kStress, kStrain };

// A finite-element model on the scene's nodes: 3-node triangles in 2D, 4-node tetrahedra in
// 3D (linear shape functions), one material or one per region.
struct FemReference {
  std::vector<std::vector<int>> elements;  // d + 1 node indices each, either orientation
  std::vector<Material> materials;         // one, or one per region
  std::vector<int> element_material;       // empty: every element has materials[0]
  // The input's own number of each element (a Gmsh mesh's element tags, a deck's element
  // ids), one per element; empty for a scene written by hand. Messages name elements by them.
  std::vector<long long> element_tags;
  bool regions = false;                  // read as "materials" + "element_materials"
  PlaneMode plane = PlaneMode::kStress;  // 2D only
  double thickness = 1.0;                // 2D only, > 0 (length)
  bool plane_given = false;              // written back only when read
  bool thickness_given = false;

  const Material& MaterialOf(std::size_t element) const {
    return materials[element_material.empty() ? 0 : element_material[element]];
  }
};

struct Reference {
  enum class Kind {
    kMss,        // a mass-spring model: springs and their stiffness; equilibria are computed
    kPositions,  // deformed positions given directly, one configuration per load case
    kFem,        // a finite-element model; equilibria are computed (engine/fem/)
  };
  Kind kind = Kind::kMss;
  std::vector<NodePair> springs;  // kMss
  std::vector<double> stiffness;  // kMss: one per spring, or a single value for all (default 1)
  std::vector<Vector> positions;  // kPositions: per load case, flat d*n positions
  FemReference fem;               // kFem
};

// The topology search strategies (engine/api/search_options.h has what each does).
enum class Strategy {
  // The best measured for the reference (bench/RESULTS.md): continuous on an FEM reference,
  // hybrid otherwise (engine/identification/strategy.h).
  kDefault,
  kPaper,   // the paper's GA, unchanged (Bianchi et al. 2003)
  kDirect,  // non-negative least squares on the force balance (engine/direct/)
  kHybrid,  // direct, then the memetic GA seeded with its topology
  // Per-spring stiffness on every candidate by sensitivities, then a sparsity path
  // (engine/fit/sparsity_path.h)
  kContinuous,
};

struct Scene;

// The strategy that runs for `scene` (the one place of that rule): the others are themselves;
// `default` is chosen from what the scene identifies:
// - continuous on an FEM reference (each spring's stiffness, fitted from the closed-form
//   baseline: the FEM has no springs to find);
// - direct when search.identify asks for topology_and_stiffness, or, left unset, the
//   reference MSS's springs differ in stiffness (a GA's topologies all carry one training
//   stiffness and cannot reproduce it: on stiff-2d hybrid misses springs that direct finds
//   exactly, bench/RESULTS.md, "Strategy direct");
// - hybrid otherwise (the topology at one stiffness: the direct topology seeding a memetic GA).
Strategy ResolvedStrategy(Strategy strategy, const Scene& scene);
// Why ResolvedStrategy chose what it did for `default`, in a few words for `springfit check`
// ("an FEM reference: ..."); "" for any other strategy.
const char* DefaultStrategyReason(Strategy strategy, const Scene& scene);

// What an identification finds (proto/SCENE.md, "search.identify").
enum class Identify {
  kTopology,              // which springs: every spring has the training stiffness (the paper)
  kTopologyAndStiffness,  // which springs and each one's stiffness (direct and continuous)
};

// How the training model responds to a load case (proto/SCENE.md, "search.response").
enum class Response {
  // The static equilibrium of the springs as they are (geometrically nonlinear: springs turn
  // as they stretch, stiffen in tension and buckle in compression). The paper's model.
  kNonlinear,
  // The linearised response at rest, K(k) u = f with K = sum k n n^T over the rest directions
  // n: the small-load limit, what a linear FEM reference describes. K does not depend on the
  // load: cases with the same fixed nodes can share a factorisation; displacements scale with
  // the load.
  kLinear,
};

// Settings of the topology search (docs/ARCHITECTURE.md, "The identification cost and the
// strategies"). An unset GA parameter takes the chosen strategy's default
// (engine/api/search_options.h).
struct SearchSettings {
  Strategy strategy = Strategy::kDefault;
  // nullopt: topology and stiffness for strategy direct, topology for the others.
  std::optional<Identify> identify;
  // nullopt: linear for an FEM reference whose materials are all linear, nonlinear otherwise
  // (Problem::response()).
  std::optional<Response> response;
  std::uint64_t seed = 1;
  std::optional<int> population;                // individuals per generation, >= 2
  std::optional<double> crossover_probability;  // in [0, 1]
  std::optional<double> mutation_probability;   // bit-flip probability per gene, in [0, 1]
  int max_generations = 1000;                   // >= 1
  std::optional<double> max_seconds;            // > 0; unset = no time limit
  std::optional<int> stall_generations;         // >= 0 (0 = never); unset = the strategy's
  // Strategy continuous (and default on an FEM reference): the model returned from the
  // sparsity path. At most this many springs (>= 1) ...
  std::optional<int> max_springs;
  // ... or the fewest springs whose relative RMS nodal error E is at most this (> 0).
  std::optional<double> target_error;
  // Strategy continuous fitted to probes: the returned model's largest stiffness over its
  // smallest, at most this (> 1): springs below the largest / this leave every model the fit
  // considers. nullopt: no bound.
  std::optional<double> max_spread;
  // Strategy continuous fitted to probes: the size of the loads the simulator will apply, as the
  // largest nodal displacement they cause, in the scene's length (> 0). The nonlinear fit, the
  // nonlinear judgement and the tool pushes run at 25, 50 and 100% of it. nullopt: the named
  // loads' size (the probe bank's amplitude).
  std::optional<double> load_size;
  // Strategy continuous: the stiffness fits' pull toward the closed-form baseline
  // (StiffnessFitOptions::regularization, >= 0), or `automatic`: chosen among
  // kRegularizationChoices by the held-out error. nullopt: 0, none.
  struct Regularization {
    bool automatic = false;
    double strength = 0.0;
  };
  std::optional<Regularization> regularization;
  // Strategy continuous on an FEM or MSS reference: the probe bank (engine/probe_fit/
  // probe_bank.h) that the model is fitted to and judged on. nullopt: automatic; 0: none (the
  // named cases alone, judged by cross-validation over them); N > 0: about N generated probes.
  std::optional<int> probes;
  // The search stops when the normalised error reaches this value (0 = exact recovery,
  // judged within the solver's relative tolerance). Unit-free, >= 0.
  double target_normalized_error = 0.0;
};

// The axis-aligned box around a set of points (flat, `dimension` coordinates per point).
struct BoundingBox {
  Vector lo;
  Vector hi;
  static BoundingBox Of(int dimension, const Vector& flat_points);
  double Diagonal() const { return (hi - lo).norm(); }
};

struct Scene {
  std::string name;
  std::string description;
  int dimension = 2;  // 2 or 3, inferred from the nodes
  Vector rest;        // flat d*n rest positions
  CandidateSpec candidates;
  Reference reference;
  std::vector<LoadCase> load_cases;
  // Named node sets, usable wherever a list of nodes is expected (fixed, loaded, tractions).
  std::map<std::string, std::vector<int>> node_sets;
  // The input's own number of each node (a Gmsh mesh's node tags, a deck's node ids), which
  // springfit renumbers from 0; empty for a scene written by hand. Exports carry them.
  std::vector<long long> node_tags;
  // Stiffness of every spring of the training model. nullopt = the reference's stiffness when
  // it is one value for all springs, otherwise 1.
  std::optional<double> training_stiffness;
  SearchSettings search;
  // The units the scene's numbers are in (proto/SCENE.md, "Units"): stated by the user, checked
  // for consistency, carried into results and exports. Absent: unstated (springfit's numbers
  // are consistent in any units; only a reader needs them).
  struct Units {
    std::string length;   // m, cm, mm, um
    std::string force;    // N, mN, uN, kN
    std::string modulus;  // Pa, kPa, MPa, GPa; empty: derived (force / length^2)
  };
  std::optional<Units> units;

  int node_count() const { return dimension == 0 ? 0 : static_cast<int>(rest.size()) / dimension; }
  // The rest positions' bounding box (needs at least one node).
  BoundingBox Bounds() const { return BoundingBox::Of(dimension, rest); }
  // The training stiffness after applying the default rule above.
  double EffectiveTrainingStiffness() const;
};

// The units of a scene (proto/SCENE.md, "Units"): a length and a force, and the stiffness and
// modulus they imply. springfit's numbers are consistent in any units; these say which, so that
// a reader (a simulator, ParaView) does not guess.
struct DerivedUnits {
  std::string length;     // as given
  std::string force;      // as given
  std::string stiffness;  // force / length, e.g. "mN/mm"
  std::string modulus;    // force / length^2 by its name where it has one (mN/mm^2 = kPa)
  // Time is the second wherever a simulator steps in time; the mass unit follows from
  // F = m a: force x s^2 / length, by its name where it has one (mN s^2/mm = kg, N s^2/mm = t).
  std::string time = "s";
  std::string mass;
};

// Checks `units` (throws InputError at "units.length", "units.force" or "units.modulus": an
// unknown unit, or a modulus that is not force / length^2) and derives the rest
// (engine/model/units.cpp).
DerivedUnits DeriveUnits(const Scene::Units& units);

// Nodes and elements as the user knows them: an imported mesh's own numbers (Gmsh's node and
// element tags, a deck's ids; Scene::node_tags, FemReference::element_tags), which springfit
// renumbers from 0. Messages name them so that the user can find them in their mesh tool
// (engine/model/mesh_names.cpp).
//
// "node 88 (the mesh's tags)", "nodes 88, 93 (the mesh's tags)"; by springfit's 0-based
// indices when the scene has no tags: "nodes 3, 4".
std::string NodesNamed(const Scene& scene, const std::vector<int>& nodes);
// "the mesh's element 1207" when the scene has element tags, else "" (the index alone is in
// the caller's path or text).
std::string MeshElementTag(const Scene& scene, std::size_t element);
// "element 31 (the mesh's element 1207)", or "element 31" without tags.
std::string ElementNamed(const Scene& scene, std::size_t element);

// An upper bound on the number of candidates the scene's CandidateSpec yields (engine/model/
// candidates.h), computed without generating them, so that a service can refuse a scene too
// large for it before the work: 4 n (2D) or 13 n (3D) on a grid, k n for k nearest (each pair
// counted from both ends at most), the pairs given, the mesh's element edges plus k n, and for
// a radius the pairs within it counted on a k-d tree, exactly, or up to the first count past
// `stop_above` (the answer then exceeds stop_above and is at most the true count). O(n log n)
// plus the pairs counted. 0 when a node coordinate is not finite (validation refuses the
// scene).
std::int64_t EstimateCandidateCount(const Scene& scene, std::int64_t stop_above);

// The semantic rules of a scene, checked once at the boundary (engine/problem/
// scene_validation.cpp). Throws InputError naming the JSON path of the first broken rule:
// - dimension 2 or 3; at least two nodes; finite coordinates; no two nodes at the same
//   position (closer than 1e-9 of the scene's extent);
// - candidate spec: k >= 1, radius > 0, spacing > 0 with one value per axis, pairs in range,
//   no self or duplicate pairs;
// - reference MSS springs in range, no self or duplicate springs, stiffness finite and > 0,
//   one value or one per spring; reference positions: one configuration per load case, each
//   with every node, finite;
// - at least one load case; node indices in range; a node at most once among a case's fixed
//   and displaced nodes; forces only on free nodes; vectors of the scene's dimension and finite;
//   every case applies some nonzero force or displacement; the constrained nodes of every case
//   remove rigid motion (two nodes in 2D, three not on one line in 3D);
// - training stiffness finite and > 0; search settings within their documented ranges.
void ValidateScene(const Scene& scene);

// A scene that passed ValidateScene: what prepares it (Problem) does not check it again. A
// submission is validated at the door, in time linear in its size, and prepared after.
class ValidScene {
 public:
  // Validates `scene` (ValidateScene); throws InputError.
  explicit ValidScene(Scene scene) : scene_(std::move(scene)) { ValidateScene(scene_); }
  const Scene& scene() const { return scene_; }
  Scene Release() && { return std::move(scene_); }

 private:
  Scene scene_;
};

}  // namespace springfit
