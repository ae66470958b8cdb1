// A scene: everything an identification needs, as plain validated data.
//
// The nodes' rest positions, the candidate springs (the node pairs that may carry a spring:
// one gene each), the reference model whose deformation the training model must reproduce,
// the load cases, the training model's stiffness and the search settings. A Scene is what the
// JSON scene format (proto/SCENE.md) describes; proto/scene_codec.h reads and validates it.
// Derived quantities (candidate list, reference equilibria, scales) live in Problem
// (problem.h), which is built from a Scene.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "engine/linalg.h"

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
  };
  Kind kind = Kind::kGrid;
  // kGrid: lattice step per axis; empty = inferred (the smallest difference between the nodes'
  // coordinates along that axis above 1e-6 of the axis's range).
  std::vector<double> spacing;
  int k = 8;            // kNearest
  double radius = 0.0;  // kRadius
  std::vector<NodePair> pairs;  // kPairs
};

// One force or prescribed displacement applied alike to one or more nodes; `value` has the
// scene's dimension. `single` records that the scene named one "node" rather than a "nodes"
// list, so that writing the scene back keeps its form.
struct NodalLoad {
  std::vector<int> nodes;
  Vector value;
  bool single = false;
};

struct LoadCase {
  std::string name;
  std::vector<int> fixed;                // nodes held at their rest position
  std::vector<NodalLoad> forces;         // external forces on free nodes (they add up)
  std::vector<NodalLoad> displacements;  // nodes moved by a prescribed displacement
};

struct Reference {
  enum class Kind {
    kMss,        // a mass-spring model: springs and their stiffness; equilibria are computed
    kPositions,  // deformed positions given directly, one configuration per load case
  };
  Kind kind = Kind::kMss;
  std::vector<NodePair> springs;  // kMss
  std::vector<double> stiffness;  // kMss: one per spring, or a single value for all (default 1)
  std::vector<Vector> positions;  // kPositions: per load case, flat d*n positions
};

// The topology search strategies (engine/search/search_options.h has what each does).
enum class Strategy {
  kDefault,  // the fastest measured (bench/RESULTS.md): today the memetic GA seeded by direct
  kPaper,    // the paper's GA, unchanged (Bianchi et al. 2003)
  kDirect,   // non-negative least squares on the force balance (engine/direct/)
  kHybrid,   // direct, then the memetic GA seeded with its topology (today's default)
};

// What an identification finds (proto/SCENE.md, "search.identify").
enum class Identify {
  kTopology,              // which springs: every spring has the training stiffness (the paper)
  kTopologyAndStiffness,  // which springs and each one's stiffness (strategy direct only)
};

// Settings of the topology search (DESIGN.md §1). An unset GA parameter takes the chosen
// strategy's default (engine/search/search_options.h).
struct SearchSettings {
  Strategy strategy = Strategy::kDefault;
  // nullopt: topology and stiffness for strategy direct, topology for the others.
  std::optional<Identify> identify;
  std::uint64_t seed = 1;
  std::optional<int> population;                // individuals per generation, >= 2
  std::optional<double> crossover_probability;  // in [0, 1]
  std::optional<double> mutation_probability;   // bit-flip probability per gene, in [0, 1]
  int max_generations = 1000;                   // >= 1
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
  // Stiffness of every spring of the training model. nullopt = the reference's stiffness when
  // it is one value for all springs, otherwise 1.
  std::optional<double> training_stiffness;
  SearchSettings search;

  int node_count() const { return dimension == 0 ? 0 : static_cast<int>(rest.size()) / dimension; }
  // The rest positions' bounding box (needs at least one node).
  BoundingBox Bounds() const { return BoundingBox::Of(dimension, rest); }
  // The training stiffness after applying the default rule above.
  double EffectiveTrainingStiffness() const;
};

}  // namespace springfit
