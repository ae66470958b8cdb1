// The closed-form baseline (engine/fem/closed_form_baseline.h) on a prepared problem: its
// stiffness over the problem's genes, and its error against the reference under the problem's
// load cases, measured as every model's is (engine/problem/cost.h).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/problem/problem.h"
#include "engine/runtime/interruption.h"

namespace springfit {

// The closed-form model as weights over the problem's genes: each mesh edge's stiffness on its
// gene, 0 on the other genes. nullopt when some mesh edge that a load case can see is not a
// candidate (the baseline is then not a model of the candidate set). Precondition as above.
std::optional<std::vector<double>> BaselineGeneWeights(const Problem& problem);

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

// nullopt unless the reference is an FEM model. Throws Interrupted when `interruption` stops
// it (checked inside its solves).
std::optional<BaselineReport> EvaluateClosedFormBaseline(const Problem& problem,
                                                         Interruption* interruption = nullptr);

}  // namespace springfit
