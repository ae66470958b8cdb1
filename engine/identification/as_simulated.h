// The named cases as the simulator runs the model (docs/ARCHITECTURE.md, "Judging a model as
// the simulator runs it"). Where the problem's response is linear (a linear FEM reference: the
// small-load limit, in which the fit and the result's E are computed), the model and the
// closed-form baseline are solved again under the named cases with the simulator's spring law
// (nonlinear springs, which turn and stretch, at the cases' own size) against the reference's
// own equilibria: what a simulator shows of the same loads. Where the response is nonlinear, E
// is that already and nothing is added.
#pragma once

#include <optional>

#include "engine/api/problem.h"
#include "engine/api/result.h"
#include "engine/runtime/interruption.h"

namespace springfit {

// E of the named cases with the spring law: the model's (infinite where it has no equilibrium
// under some case: a mechanism, or no convergence) and the closed-form baseline's (an FEM
// reference only). nullopt where the problem's response is nonlinear, or when `interruption`
// stops it (a stopped run is not judged again).
std::optional<IdentificationResult::AsSimulated> NamedCasesAsSimulated(
    const Problem& problem, const IdentificationResult& result, Interruption* interruption);

}  // namespace springfit
