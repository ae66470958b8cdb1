// The output of `springfit reference` (proto/SCENE.md, "Getting at the reference"): the
// reference's equilibrium positions per load case, as a positions reference that can be pasted
// into a scene, and how each was solved.
#pragma once

#include "engine/problem.h"
#include "proto/json_reader.h"

namespace springfit::proto {

// {"reference": {"type": "positions", "positions": [...]}, "load_cases": [{"name", "iterations",
//  "load_steps", "residual", "max_displacement"}, ...]}; the solver fields only where the
// reference was solved (mss, fem).
Json ReferenceSolutionToJson(const Problem& problem);

}  // namespace springfit::proto
