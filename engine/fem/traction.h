// Distributed boundary loads of a finite-element reference turned into nodal forces.
//
// A traction acts on the boundary facets (edges of triangles in 2D, faces of tetrahedra in 3D,
// each belonging to exactly one element) whose nodes all belong to its node set. For a
// constant traction t on a linear facet of measure A (length in 2D, area in 3D) the
// consistent nodal forces (the work-equivalent ones, int N_a t dA) are t A / d on each of
// its d nodes. A total force T is spread as the constant traction T / (sum of the facets'
// measures).
#pragma once

#include <string>
#include <vector>

#include "engine/api/scene.h"

namespace springfit::fem {

// The boundary facets of the mesh, each as its d node indices (ascending), in a fixed order.
std::vector<std::vector<int>> BoundaryFacets(const FemReference& fem, int dimension);

// Adds the traction's nodal forces into `force` (flat d*n). Throws InputError(path + ".on")
// when the node set holds no boundary facet.
void AddTractionForces(const Scene& scene, const Traction& traction, const std::string& path,
                       Vector& force);

}  // namespace springfit::fem
