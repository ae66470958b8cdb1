// Meshes in: a tissue mesh from the files users' tools write, made into a scene (proto/
// SCENE.md) whose FEM reference is the mesh, and whose node sets are the mesh's named groups.
// The rest of the scene (material, load cases, search settings) comes from a loads file: a
// partial scene merged over what the mesh gives (proto/IMPORT.md).
#pragma once

#include <array>
#include <map>
#include <string>
#include <vector>

#include "proto/json_reader.h"

namespace springfit::io {

// A linear simplex mesh as read from a file, nodes renumbered from 0.
struct ImportedMesh {
  std::string source;                      // the file
  int dimension = 2;                       // 2: triangles in the plane z = 0; 3: tetrahedra
  std::vector<double> nodes;               // flat, `dimension` per node
  std::vector<long long> node_tags;        // each node's Gmsh tag
  std::vector<std::vector<int>> elements;  // triangles or tetrahedra
  std::vector<long long> element_tags;     // each element's Gmsh tag
  // Per element, the name of the region (physical surface in 2D, volume in 3D) it belongs to;
  // empty when the mesh names none.
  std::vector<std::string> element_regions;
  // Named groups of any dimension (points, curves, surfaces, volumes): their nodes, sorted.
  std::map<std::string, std::vector<int>> node_sets;
  std::map<std::string, int> region_elements;  // elements per region, for reports
};

// Gmsh .msh (2.2 or 4.1, ASCII or binary) through the Gmsh library. Keeps the nodes of the
// triangles (2D) or tetrahedra (3D); a physical group's name names its nodes (an unnamed group
// is named by its tag). Throws InputError naming the file: unreadable, no triangle or
// tetrahedron, elements springfit has no FEM for (quadrangles, second order, ...), a 2D mesh
// off the plane z = 0.
ImportedMesh ReadGmshMesh(const std::string& path);

// The scene of `mesh` (name: the file's stem) with `loads` (an object, or null) merged over it:
// objects field by field, everything else replaced; `reference.materials` may be an object
// keyed by region name (made into `materials` and `element_materials`). `loads_name` names the
// loads in messages. Throws InputError naming the loads file and field.
proto::Json SceneOfMesh(const ImportedMesh& mesh, const proto::Json& loads,
                        const std::string& loads_name);

// CalculiX/Abaqus input decks (.inp): *NODE, *ELEMENT (CPS3, CPE3, C3D4; T2D2, T3D2 trusses
// as an MSS reference), *NSET / *ELSET (GENERATE), *MATERIAL / *ELASTIC, *SOLID SECTION,
// *BOUNDARY, *CLOAD, *DLOAD (pressures on C3D4 faces), *INCLUDE, and each *STEP a load case
// from rest (NLGEOM: St. Venant-Kirchhoff; a step that would inherit the earlier steps' loads
// or holds in CalculiX is refused). Several decks of one model give their steps in order.
// Output requests and solver controls are skipped; any other keyword or parameter is an error
// naming its file and line.
bool IsAbaqusDeck(const std::string& path);
// What reading decks finds beside the scene.
struct DeckImport {
  std::vector<long> node_ids;  // the deck's id of each scene node
  // Without *SOLID SECTION: each element's region (its first *ELSET of mesh elements; empty
  // for none), for materials by region in --loads; the elements per region.
  std::vector<std::string> element_regions;
  std::map<std::string, int> region_elements;
  bool has_sections = true;  // false: the material must come from --loads
  bool has_steps = true;     // false: the load cases must come from --loads
  // One line each, for the user: elements left out, inverted elements, what CPS3 means here.
  std::vector<std::string> notes;
};
proto::Json SceneOfAbaqusDecks(const std::vector<std::string>& paths, DeckImport* found = nullptr);

// Nodal displacements (by node id) per step from CalculiX results: a .frd file (*NODE FILE, U;
// per step its last increment) or a .dat file (*NODE PRINT, U; its last block: one file per
// step). Throws InputError naming the file and line.
std::vector<std::map<long, std::array<double, 3>>> ReadCalculixDisplacements(
    const std::string& path);

// Whether `path` names a file this importer reads (by extension: .msh, .inp).
bool IsMeshFile(const std::string& path);

// The scene of a Gmsh mesh, or of one or several decks, with the loads file at `loads_path`
// (empty: no loads) merged over it. Throws InputError naming the file. `notes` (when given)
// receives what the user should know of the import (DeckImport::notes).
// With `results` (CalculiX .frd / .dat, decks only), the reference is those positions: one
// step's displacements per load case, in order, and the candidates the elements' edges.
proto::Json ImportSceneFiles(const std::vector<std::string>& paths, const std::string& loads_path,
                             const std::vector<std::string>& results = {},
                             std::vector<std::string>* notes = nullptr);

}  // namespace springfit::io
