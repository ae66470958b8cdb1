// The output of `springfit reference` (proto/SCENE.md, "Getting at the reference"): the
// reference's equilibrium positions per load case, as a positions reference that can be pasted
// into a scene, and how each was solved.
#pragma once

#include "engine/api/problem.h"
#include "proto/json_reader.h"

namespace springfit::proto {

// {"reference": {"type": "positions", "positions": [...]}, "load_cases": [...], "solves":
//  [{"name", "iterations", "load_steps", "residual", "max_displacement"}, ...]}. "reference" and
// "load_cases" replace a scene's own to make it a positions scene: a load case with tractions
// (which need the FEM mesh) is written with them turned into the nodal forces they give. The
// solver fields only where the reference was solved (mss, fem).
Json ReferenceSolutionToJson(const Problem& problem);

}  // namespace springfit::proto
