// Candidate springs: the node pairs that may carry a spring, one gene each.
#pragma once

#include <cstdint>
#include <vector>

#include "engine/model/scene.h"

namespace springfit {

// Generates the candidate pairs of `scene` from its CandidateSpec, sorted by (first, second),
// without duplicates. Throws InputError (path "candidates...") when the spec cannot be applied,
// e.g. a grid whose nodes are not on a lattice. Preconditions: the nodes are valid (finite,
// distinct) and kPairs entries are in range and not self pairs.
std::vector<NodePair> GenerateCandidates(const Scene& scene);

// An upper bound on the number of candidates GenerateCandidates(scene) yields, computed
// without generating them, so that a service can refuse a scene too large for it before the
// work: 4 n (2D) or 13 n (3D) on a grid, k n for k nearest (each pair counted from both ends
// at most), the pairs given, the mesh's element edges plus k n, and for a radius the pairs
// within it counted on a k-d tree, exactly, or up to the first count past `stop_above` (the
// answer then exceeds stop_above and is at most the true count). O(n log n) plus the pairs
// counted. 0 when a node coordinate is not finite (validation refuses the scene).
std::int64_t EstimateCandidateCount(const Scene& scene, std::int64_t stop_above);

// The per-axis lattice step of `scene`'s nodes: the smallest difference between node
// coordinates along each axis that exceeds 1e-6 of the axis's range (0 for an axis on which
// all nodes agree).
std::vector<double> InferLatticeSpacing(const Scene& scene);

}  // namespace springfit
