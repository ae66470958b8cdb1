// The built-in example scenes by name (`springfit example NAME`, also committed under
// examples/): the engine's builders (engine/examples/catalog.h), and the kidney's meshes read
// from their Gmsh files (examples/meshes/, built into the program: offline, no file at run
// time) through the same importer as users' meshes (mesh_import.h).
#pragma once

#include <string>
#include <vector>

#include "engine/api/examples.h"

namespace springfit::examples {

struct ExampleInfo {
  std::string name;
  std::string description;
};

// Names and one-line descriptions, in catalogue order.
const std::vector<ExampleInfo>& Catalog();

// Builds the named example; throws std::invalid_argument for an unknown name.
Scene Make(const std::string& name);

// The kidney cross-section meshed by gmsh (examples/meshes/kidney-2d.geo, kidney-2d.msh): 99
// nodes, 165 triangles; and the same outline meshed finer (kidney-2d-fine.msh, lc 0.325): 626
// nodes, 1164 triangles. Read once.
const SimplexMesh& KidneyMesh();
const SimplexMesh& KidneyMeshFine();

}  // namespace springfit::examples
