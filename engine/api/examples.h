// The engine's public surface (engine/api/): the built-in example scenes' builders
// (engine/examples/: catalog.cpp, fem_examples.cpp), also committed under examples/. Each builds
// its scene deterministically and checks that the reference stays unambiguous under every
// load case: no cell of the mesh inverts (docs/ARCHITECTURE.md, "Paper7 load cases").
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "engine/api/scene.h"
#include "engine/linalg/linalg.h"

namespace springfit::examples {

// A simplex mesh: triangles in 2D, tetrahedra in 3D (engine/examples/simplex_mesh.h builds the
// structured ones; io/example_catalog.h reads the kidney's).
struct SimplexMesh {
  Vector nodes;                            // flat d*n rest positions, x fastest, then y (then z)
  std::vector<std::vector<int>> elements;  // triangles or tetrahedra, positively oriented
};

// The paper's 5x5 grids (isotropic or anisotropic reference), a 4x4x4 grid, a grid of varied
// stiffness.
Scene PaperGrid(const std::string& name, bool anisotropic);
Scene Grid3d();
Scene Stiff2d();
// An MSS reference on the edges of a triangulated kidney cross-section `mesh`.
Scene Kidney2d(const SimplexMesh& mesh);

// The FEM examples (fem_examples.cpp): the paper7 patterns as tractions on named node sets,
// scaled to 5% strain in the small-load limit.
Scene FemPlate5x5();
// On the kidney's mesh (io/example_catalog.h, KidneyMesh).
Scene FemKidney2d(const SimplexMesh& mesh, bool nonlinear);
// fem-kidney-2d on the fine mesh (KidneyMeshFine): the size of a simulator's organ section.
Scene FemKidney2dFine(const SimplexMesh& mesh);
Scene FemBlock3d();

// The scene with its reference replaced by measured positions: the reference's equilibrium
// positions under each load case, each coordinate of every free node perturbed by Gaussian
// noise of standard deviation `fraction` times that load case's RMS nodal displacement (over
// its free nodes). Constrained nodes keep their exact positions. Deterministic in `seed`
// (Box-Muller on the project's own random stream, so every platform draws the same noise).
Scene WithMeasurementNoise(const Scene& scene, double fraction, std::uint64_t seed);

}  // namespace springfit::examples
