// The closed-form baseline (engine/fem/closed_form_baseline.h) on a prepared problem: its
// stiffness over the problem's genes, and its error against the reference under the problem's
// load cases, measured as every model's is (engine/problem/cost.h).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "engine/api/analysis.h"
#include "engine/api/problem.h"
#include "engine/runtime/interruption.h"

namespace springfit {

// The closed-form model as weights over the problem's genes: each mesh edge's stiffness on its
// gene, 0 on the other genes. nullopt when some mesh edge that a load case can see is not a
// candidate (the baseline is then not a model of the candidate set). Precondition as above.
std::optional<std::vector<double>> BaselineGeneWeights(const Problem& problem);

// BaselineReport, what a result shows of the baseline, is on the surface (engine/api/analysis.h).

// nullopt unless the reference is an FEM model. Throws Interrupted when `interruption` stops
// it (checked inside its solves).
std::optional<BaselineReport> EvaluateClosedFormBaseline(const Problem& problem,
                                                         Interruption* interruption = nullptr);

}  // namespace springfit
