// The identified mass-spring model as a simulator loads it: the nodes at rest and every
// spring with its stiffness and rest length. What every exporter writes (model_writers.h),
// built from a result and its scene, whatever the strategy.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/problem.h"
#include "engine/units.h"
#include "proto/search_codec.h"

namespace springfit::io {

struct SpringModel {
  std::string name;         // the scene's
  std::string description;  // where it comes from: strategy, seed, E, units
  // The scene's units (engine/units.h), when it states them.
  std::optional<DerivedUnits> units;
  int dimension = 2;         // 2 or 3
  std::vector<double> rest;  // flat rest positions, `dimension` per node

  struct Spring {
    int a = 0, b = 0;  // nodes, a < b
    double stiffness = 0.0;
    double rest_length = 0.0;  // the nodes' distance at rest: the springs are unloaded there
    // False where the load cases do not determine the stiffness (no load case loads the
    // spring, or it is in a group of springs they cannot tell apart, or both its nodes are
    // held in every case): the value is then the fit's or the training stiffness, not data.
    bool identified = true;
  };
  std::vector<Spring> springs;

  int node_count() const { return static_cast<int>(rest.size()) / dimension; }
};

// The model of `result` (a result of `problem`'s scene): its springs with their stiffness (the
// training stiffness where the result has none, as for topology-only strategies), then the
// candidates no load case can see, at the training stiffness and not identified, so that the
// model is complete. Throws InputError when the result does not fit the scene (another scene's
// name or gene count, a spring that is no candidate).
SpringModel ModelOfResult(const Problem& problem, const proto::StoredResult& result);

}  // namespace springfit::io
