// The reference's displacements u^R under each prepared load case, one function per kind of
// reference: an MSS's and an FEM model's equilibria solved from rest, a positions reference's
// measured positions taken as they are. Steps of preparing a Problem (problem.h); each fills
// `reference` and `reference_solve` of every load case and throws InputError naming the load
// case when the reference cannot carry it, or Interrupted when `interruption` stops it.
#pragma once

#include <vector>

#include "engine/api/problem.h"
#include "engine/model/equilibrium.h"
#include "engine/runtime/interruption.h"

namespace springfit {

// The reference MSS's equilibria, polished down to round-off (strategy direct reads stiffness
// off their force balance), each checked for being determined in double precision.
void SolveMssReference(const Scene& scene, const std::vector<FreeNodes>& free_sets,
                       const EquilibriumOptions& solver_options,
                       std::vector<PreparedLoadCase>& load_cases, Interruption* interruption);

// The FEM reference's equilibria (engine/fem/): one solver per set of free nodes.
void SolveFemReference(const Scene& scene, const std::vector<FreeNodes>& free_sets,
                       std::vector<PreparedLoadCase>& load_cases, Interruption* interruption);

// The measured positions as displacements. A constrained node's measured position must be its
// prescribed one within `tolerance` (a length; round-off in exported data), and is then set to
// it exactly.
void TakePositionsReference(const Scene& scene, const std::vector<FreeNodes>& free_sets,
                            double tolerance, std::vector<PreparedLoadCase>& load_cases);

}  // namespace springfit
