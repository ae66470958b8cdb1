// Gmsh .msh files through the Gmsh library (Debian libgmsh-dev): Gmsh parses every version and
// encoding it writes; this maps its model (nodes with tags, elements by type, physical groups)
// onto springfit's numbering.
#include <gmsh.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <unordered_map>

#include "engine/api/input_error.h"
#include "io/gmsh_session.h"
#include "io/mesh_import.h"

namespace springfit::io {
namespace {

constexpr int kTriangle = 2;     // Gmsh's 3-node triangle
constexpr int kTetrahedron = 4;  // Gmsh's 4-node tetrahedron

// A physical group's name, or its tag when it has none.
std::string GroupName(int dim, int tag) {
  std::string name;
  gmsh::model::getPhysicalName(dim, tag, name);
  return name.empty() ? std::to_string(tag) : name;
}

// The mesh's dimension: its highest elements', which must be linear simplices.
int MeshDimension(const std::string& path) {
  std::vector<int> types;
  gmsh::model::mesh::getElementTypes(types);
  int top = 0;
  for (int type : types) {
    std::string name;
    int dim = 0, order = 0, nodes = 0, primary = 0;
    std::vector<double> local;
    gmsh::model::mesh::getElementProperties(type, name, dim, order, nodes, local, primary);
    top = std::max(top, dim);
  }
  if (top < 2) {
    throw InputError("", path +
                             ": no triangles or tetrahedra (a 2D or 3D mesh is needed; "
                             "mesh the surfaces or volumes: gmsh -2 or -3)");
  }
  for (int type : types) {
    std::string name;
    int dim = 0, order = 0, nodes = 0, primary = 0;
    std::vector<double> local;
    gmsh::model::mesh::getElementProperties(type, name, dim, order, nodes, local, primary);
    if (dim == top && type != kTriangle && type != kTetrahedron) {
      std::vector<std::size_t> tags, node_tags;
      gmsh::model::mesh::getElementsByType(type, tags, node_tags);
      throw InputError("", path + ": " + std::to_string(tags.size()) + " elements of Gmsh type " +
                               std::to_string(type) + " (" + name +
                               "): springfit's FEM takes 3-node triangles (2D) and 4-node "
                               "tetrahedra (3D) only (mesh with Mesh.RecombineAll 0 and "
                               "Mesh.ElementOrder 1)");
    }
  }
  return top;
}

// The elements, entity by entity, so that each knows its region: their Gmsh node tags, `per`
// to an element, and their regions into `mesh`.
std::vector<std::size_t> ReadElements(const std::string& path, int top,
                                      const gmsh::vectorpair& groups, ImportedMesh& mesh) {
  const int type = top == 2 ? kTriangle : kTetrahedron;
  std::unordered_map<int, std::string> region_of_entity;
  for (const auto& [dim, tag] : groups) {
    if (dim != top) continue;
    std::vector<int> entities;
    gmsh::model::getEntitiesForPhysicalGroup(dim, tag, entities);
    for (int e : entities) region_of_entity[e] = GroupName(dim, tag);
  }
  gmsh::vectorpair entities;
  gmsh::model::getEntities(entities, top);
  std::vector<std::size_t> element_nodes;  // Gmsh node tags
  for (const auto& [dim, entity] : entities) {
    std::vector<std::size_t> tags, node_tags;
    gmsh::model::mesh::getElementsByType(type, tags, node_tags, entity);
    element_nodes.insert(element_nodes.end(), node_tags.begin(), node_tags.end());
    mesh.element_tags.insert(mesh.element_tags.end(), tags.begin(), tags.end());
    const auto region = region_of_entity.find(entity);
    const std::string name = region == region_of_entity.end() ? "" : region->second;
    mesh.element_regions.insert(mesh.element_regions.end(), tags.size(), name);
    if (!name.empty()) mesh.region_elements[name] += static_cast<int>(tags.size());
  }
  if (element_nodes.empty()) {
    throw InputError(
        "", path + ": no " + std::string(top == 2 ? "triangles" : "tetrahedra") + " in the mesh");
  }
  return element_nodes;
}

// The nodes the elements use, in the order of their Gmsh tags, into `mesh`; returns each one's
// index by tag. A plane mesh is 2D when every node has z = 0 (within round-off of its size).
std::unordered_map<std::size_t, int> ReadNodes(const std::string& path, int top,
                                               const std::vector<std::size_t>& element_nodes,
                                               ImportedMesh& mesh) {
  std::vector<std::size_t> all_tags;
  std::vector<double> coords, parametric;
  gmsh::model::mesh::getNodes(all_tags, coords, parametric, -1, -1, true, false);
  std::unordered_map<std::size_t, std::size_t> position_of_tag;  // into all_tags
  for (std::size_t i = 0; i < all_tags.size(); ++i) position_of_tag.emplace(all_tags[i], i);
  std::vector<std::size_t> used(element_nodes.begin(), element_nodes.end());
  std::sort(used.begin(), used.end());
  used.erase(std::unique(used.begin(), used.end()), used.end());
  double extent = 0.0, largest_z = 0.0;
  for (std::size_t tag : used) {
    const auto at = position_of_tag.find(tag);
    if (at == position_of_tag.end())
      throw InputError("", path + ": an element uses node " + std::to_string(tag) +
                               ", which the mesh does not define");
    for (int c = 0; c < 3; ++c) extent = std::max(extent, std::abs(coords[3 * at->second + c]));
    largest_z = std::max(largest_z, std::abs(coords[3 * at->second + 2]));
  }
  if (top == 2 && largest_z > 1e-12 * extent) {
    throw InputError("", path + ": a 2D mesh must lie in the plane z = 0 (a node has z = " +
                             std::to_string(largest_z) +
                             "); a surface in space is not a plane model. A 3D geometry "
                             "meshed with `gmsh -2` gives its surface only: mesh it with "
                             "`gmsh -3` for tetrahedra");
  }
  std::unordered_map<std::size_t, int> index_of_tag;
  for (std::size_t tag : used) {
    index_of_tag.emplace(tag, static_cast<int>(index_of_tag.size()));
    mesh.node_tags.push_back(static_cast<long long>(tag));
    const std::size_t at = position_of_tag[tag];
    for (int c = 0; c < top; ++c) mesh.nodes.push_back(coords[3 * at + c]);
  }
  return index_of_tag;
}

// Named groups as node sets (groups of one name, in several dimensions, are one set).
void ReadNodeSets(const gmsh::vectorpair& groups,
                  const std::unordered_map<std::size_t, int>& index_of_tag, ImportedMesh& mesh) {
  std::map<std::string, std::set<int>> sets;
  for (const auto& [dim, tag] : groups) {
    std::vector<std::size_t> node_tags;
    std::vector<double> group_coords;
    gmsh::model::mesh::getNodesForPhysicalGroup(dim, tag, node_tags, group_coords);
    std::set<int>& set = sets[GroupName(dim, tag)];
    for (std::size_t t : node_tags) {
      const auto it = index_of_tag.find(t);
      if (it != index_of_tag.end()) set.insert(it->second);
    }
  }
  for (auto& [name, set] : sets) {
    if (!set.empty()) mesh.node_sets[name] = std::vector<int>(set.begin(), set.end());
  }
}

}  // namespace

ImportedMesh ReadGmshMesh(const std::string& path) {
  if (!std::filesystem::is_regular_file(path)) throw InputError("", path + ": no such file");
  GmshSession session;
  ImportedMesh mesh;
  mesh.source = path;
  GmshCall(path, "cannot read the mesh", [&] { gmsh::open(path); });
  const int top = MeshDimension(path);
  gmsh::vectorpair groups;
  gmsh::model::getPhysicalGroups(groups);
  const std::vector<std::size_t> element_nodes = ReadElements(path, top, groups, mesh);
  const std::unordered_map<std::size_t, int> index_of_tag =
      ReadNodes(path, top, element_nodes, mesh);
  mesh.dimension = top;
  const int per = top == 2 ? 3 : 4;
  for (std::size_t e = 0; e < element_nodes.size() / per; ++e) {
    std::vector<int> element;
    for (int k = 0; k < per; ++k) element.push_back(index_of_tag.at(element_nodes[per * e + k]));
    mesh.elements.push_back(std::move(element));
  }
  bool any_region = false;
  for (const std::string& r : mesh.element_regions) any_region = any_region || !r.empty();
  if (!any_region) mesh.element_regions.clear();
  ReadNodeSets(groups, index_of_tag, mesh);
  return mesh;
}

}  // namespace springfit::io
