// Candidate springs: the node pairs that may carry a spring, one gene each.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/api/scene.h"

namespace springfit {

// Generates the candidate pairs of `scene` from its CandidateSpec, sorted by (first, second),
// without duplicates. Throws InputError (path "candidates...") when the spec cannot be applied,
// e.g. a grid whose nodes are not on a lattice. Preconditions: the nodes are valid (finite,
// distinct) and kPairs entries are in range and not self pairs.
std::vector<NodePair> GenerateCandidates(const Scene& scene);

// EstimateCandidateCount, which a service calls before the work, is on the surface
// (engine/api/scene.h).

// The per-axis lattice step of `scene`'s nodes: the smallest difference between node
// coordinates along each axis that exceeds 1e-6 of the axis's range (0 for an axis on which
// all nodes agree).
std::vector<double> InferLatticeSpacing(const Scene& scene);

}  // namespace springfit
