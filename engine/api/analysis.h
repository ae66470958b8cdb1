// The engine's public surface (engine/api/): analyses shown beside a scene or a model: which
// springs the load cases identify, the FEM mesh's measures and quality, the probe fit's and the
// certificate's reports (probe families, E summaries, pencils), the closed-form baseline's
// error.
#pragma once

#include <string>

#include "engine/api/identifiability_report.h"
#include "engine/api/mesh_facts.h"
#include "engine/api/probe_fit_report.h"

namespace springfit {

// The closed-form baseline's error against the reference under the named load cases
// (engine/problem/baseline_evaluation.h computes it).
struct BaselineReport {
  std::string recipe = "van_gelder_1998";
  int springs = 0;
  // The baseline model's equilibria against the reference's, over the free nodes of every
  // load case (as the cost, engine/problem/cost.h): e = sum |u_mss - u_ref|^2 / sum |u_ref|^2 and
  // the relative RMS nodal error E = sqrt(e). Only meaningful when `converged`.
  double normalized_error = 0.0;
  double rms_error = 0.0;
  bool converged = true;  // false: the baseline has no equilibrium under some load case
};

}  // namespace springfit
