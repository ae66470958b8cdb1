// Structured simplex meshes: a triangulated rectangle and a tetrahedral block, for the FEM
// examples, tests and benchmarks.
#pragma once

#include <vector>

#include "engine/api/examples.h"
#include "engine/linalg/linalg.h"

namespace springfit::examples {

// (nx + 1) x (ny + 1) nodes on [0, nx h] x [0, ny h]; each cell split into two triangles, by
// the '/' diagonal everywhere, or alternating '/' and '\' like a chequerboard (`alternate`).
SimplexMesh TriangulatedRectangle(int nx, int ny, double h, bool alternate);

// (nx + 1) x (ny + 1) x (nz + 1) nodes of spacing h; each cube split into the six tetrahedra
// around its main diagonal (Kuhn's subdivision: conforming, since every face is cut along the
// diagonal through its lowest and highest corners).
SimplexMesh TetrahedralBlock(int nx, int ny, int nz, double h);

}  // namespace springfit::examples
