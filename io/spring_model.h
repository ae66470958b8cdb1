// The identified mass-spring model as a simulator loads it: the nodes at rest and every
// spring with its stiffness and rest length. What every exporter writes (model_writers.h),
// built from a result and its scene, whatever the strategy.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "engine/api/problem.h"
#include "engine/api/scene.h"
#include "proto/search_codec.h"

namespace springfit::io {

// How an export builds the model beyond the result: masses and dead springs. Defaults as
// documented; Validate() throws InputError naming the option.
struct ModelOptions {
  // Mass per volume lumped onto the nodes of the FEM reference's mesh (each element's mass in
  // equal shares to its d + 1 nodes), overriding the materials' `density`. nullopt: the
  // materials' own, when every material states one.
  std::optional<double> density;
  // Every node this mass instead (any scene, also one without a mesh). Not with `density`.
  std::optional<double> node_mass;
  // Springs stiffer than nothing but weaker than this fraction of the median stiffness are
  // dead: they carry no load a simulator would notice and only slow an explicit integrator
  // down by nothing. Flagged (`dead`), or left out with drop_dead. In [0, 1).
  double dead_fraction = 1e-3;
  bool drop_dead = false;
  void Validate() const;
};

struct SpringModel {
  std::string name;         // the scene's
  std::string description;  // where it comes from: strategy, seed, E, units
  // The scene's units (DerivedUnits, engine/api/scene.h), when it states them.
  std::optional<DerivedUnits> units;
  int dimension = 2;                 // 2 or 3
  std::vector<double> rest;          // flat rest positions, `dimension` per node
  std::vector<long long> node_tags;  // the input's own node numbers (Scene::node_tags), or empty
  // The response the model was judged with (Problem::response): "linear" (the linearised
  // response at rest) or "nonlinear" (springs that turn and stretch).
  std::string response;

  // Whether the load cases determine a spring's stiffness. Numeric fields write it as its
  // value (1, 0, -1), the JSON model as true, false or null.
  enum class Identified { kNo = 0, kYes = 1, kNotAnalysed = -1 };
  struct Spring {
    int a = 0, b = 0;  // nodes, a < b
    double stiffness = 0.0;
    double rest_length = 0.0;  // the nodes' distance at rest: the springs are unloaded there
    // kNo where the load cases do not determine the stiffness (no load case loads the
    // spring, or it is in a group of springs they cannot tell apart, or both its nodes are
    // held in every case): the value is then the fit's or the training stiffness, not data.
    // kNotAnalysed where that was not analysed (SpringModel::groups_not_analysed says why):
    // it may or may not be determined.
    Identified identified = Identified::kYes;
    // Below ModelOptions::dead_fraction of the fitted springs' median stiffness (kept:
    // drop_dead was false).
    bool dead = false;
    // Not the result's: a candidate between held nodes that the export adds (its stiffness the
    // problem's for it), so that the model is complete.
    bool between_held = false;
  };
  std::vector<Spring> springs;
  // Why the scene's dependent groups were not analysed (IdentifiabilityReport::not_analysed),
  // where some spring is kNotAnalysed; empty otherwise or when the result did not say.
  std::string groups_not_analysed;

  // Mass per node (empty: none known: no density and no node mass given), and how it was
  // found, in words ("density 1e-06 lumped on the 380 triangles").
  std::vector<double> mass;
  std::string mass_source;

  // The FEM reference's mesh (triangles or tetrahedra, node indices), empty for other
  // references; the scene's node sets. For viewers and a simulator's visual or collision mesh.
  std::vector<std::vector<int>> elements;
  std::map<std::string, std::vector<int>> node_sets;

  // Each load case of the scene as a simulator applies it, and the two answers to compare.
  struct LoadCase {
    std::string name;
    std::vector<int> held;      // nodes held: fixed, or moved by a prescribed displacement
    std::vector<double> start;  // flat: rest, with the prescribed nodes moved
    std::vector<double> force;  // flat external forces (tractions resolved), 0 on held nodes
    std::vector<double> reference_displacement;  // flat, the reference's equilibrium
    // Flat, the model's own equilibrium under the case (its response), empty when it has
    // none (a mechanism, or a solve that did not converge).
    std::vector<double> model_displacement;
  };
  std::vector<LoadCase> load_cases;

  // What a simulator needs to know of the springs and masses (model_facts.h).
  struct Facts {
    // Of the springs the model holds (with drop_dead, the kept ones; with the springs between
    // held nodes).
    double min_stiffness = 0.0, median_stiffness = 0.0, max_stiffness = 0.0;
    // The median of the result's springs, dead ones included: the median `run` and `result`
    // print, and the base of the dead threshold (dead_fraction x it).
    double fitted_median_stiffness = 0.0;
    double dead_fraction = 0.0;
    double dead_threshold = 0.0;
    int dead = 0;  // springs below it (dropped or flagged)
    bool dead_dropped = false;
    std::optional<double> total_mass;
    // The largest step of an explicit integrator (symplectic Euler, central differences) that
    // stays stable without damping: 2 / omega_max, from a bound on omega_max (safe).
    std::optional<double> stable_time_step;
  };
  Facts facts;

  int node_count() const { return static_cast<int>(rest.size()) / dimension; }
};

// The model of `result` (a result of `problem`'s scene): its springs with their stiffness (the
// training stiffness where the result has none, as for topology-only strategies), then the
// candidates no load case can see, at the training stiffness and not identified, so that the
// model is complete; masses, load cases with both equilibria, and facts. Throws InputError
// when the result does not fit the scene (another scene's name or gene count, a spring that is
// no candidate) or the options do not fit it (a density without a mesh, materials without a
// density for some).
SpringModel ModelOfResult(const Problem& problem, const proto::StoredResult& result,
                          const ModelOptions& options = {});

}  // namespace springfit::io
