// A mesh made into a scene, and a loads file merged over it (mesh_import.h, proto/IMPORT.md).
#include <algorithm>
#include <filesystem>

#include "engine/input_error.h"
#include "io/mesh_import.h"
#include "proto/scene_codec.h"

namespace springfit::io {
namespace {

using proto::Json;

// An error in the loads file: "LOADS: FIELD: MESSAGE".
InputError LoadsError(const std::string& where, const std::string& field,
                      const std::string& message) {
  return InputError("", where + ": " + field + ": " + message);
}

// The loads' fields: the parts of a scene a mesh does not give.
const char* const kLoadsFields[] = {"name",       "description", "reference", "candidates",
                                    "load_cases", "stiffness",   "search",    "node_sets"};

// `patch` merged into `target`: objects field by field (recursively), anything else replaced.
void MergeInto(Json& target, const Json& patch) {
  if (!patch.is_object() || !target.is_object()) {
    target = patch;
    return;
  }
  for (const auto& [key, value] : patch.items()) MergeInto(target[key], value);
}

// `reference.materials` given as {region: material}: the scene's `materials` array and one
// index per element.
void ResolveRegionMaterials(Json& reference, const ImportedMesh& mesh, const std::string& where) {
  if (!reference.contains("materials") || !reference["materials"].is_object()) return;
  const Json by_region = reference["materials"];
  std::string regions;
  for (const auto& [name, count] : mesh.region_elements)
    regions += (regions.empty() ? "" : ", ") + name;
  if (mesh.element_regions.empty()) {
    throw LoadsError(where, "reference.materials",
                     "materials by region, but " + mesh.source +
                         " names no region (a physical group of its " +
                         (mesh.dimension == 2 ? "surfaces" : "volumes") + ")");
  }
  Json materials = Json::array();
  std::map<std::string, int> index;
  for (const auto& [name, material] : by_region.items()) {
    if (!mesh.region_elements.count(name)) {
      throw LoadsError(where, "reference.materials." + name,
                       "no region of " + mesh.source + " is named '" + name +
                           "' (its regions: " + regions + ")");
    }
    index[name] = static_cast<int>(materials.size());
    materials.push_back(material);
  }
  Json element_materials = Json::array();
  for (std::size_t e = 0; e < mesh.element_regions.size(); ++e) {
    const auto it = index.find(mesh.element_regions[e]);
    if (it == index.end()) {
      throw LoadsError(
          where, "reference.materials",
          "region '" +
              (mesh.element_regions[e].empty() ? std::string("(none)") : mesh.element_regions[e]) +
              "' of " + mesh.source + " (element " + std::to_string(e) + ") has no material");
    }
    element_materials.push_back(it->second);
  }
  reference["materials"] = std::move(materials);
  reference["element_materials"] = std::move(element_materials);
}

// `loads` merged over a scene a mesh or deck gave (no-op for null).
void MergeLoads(Json& scene, const Json& loads, const std::string& where) {
  if (loads.is_null()) return;
  if (!loads.is_object())
    throw InputError("", where + ": the loads are a JSON object (proto/IMPORT.md)");
  for (const auto& [key, value] : loads.items()) {
    if (std::find(std::begin(kLoadsFields), std::end(kLoadsFields), key) ==
        std::end(kLoadsFields)) {
      throw LoadsError(where, key,
                       "unknown field (a loads file gives name, description, "
                       "reference, candidates, load_cases, stiffness, search, "
                       "node_sets; the mesh gives the nodes)");
    }
  }
  if (loads.contains("reference")) {
    const Json& r = loads["reference"];
    if (!r.is_object()) throw LoadsError(where, "reference", "expected an object");
    const Json& given = scene["reference"]["type"];
    if (r.contains("type") && r["type"] != given) {
      throw LoadsError(where, "reference.type",
                       "the mesh's reference is of type " + given.get<std::string>() +
                           " (its elements); got " + r["type"].dump());
    }
    if (r.contains("elements"))
      throw LoadsError(where, "reference.elements", "the mesh gives the elements");
  }
  if (loads.contains("node_sets")) {
    const Json& sets = loads["node_sets"];
    if (!sets.is_object()) throw LoadsError(where, "node_sets", "expected an object");
    for (const auto& [name, value] : sets.items()) {
      if (scene.contains("node_sets") && scene["node_sets"].contains(name)) {
        throw LoadsError(where, "node_sets." + name,
                         "the mesh already has a group named '" + name + "'");
      }
    }
  }
  MergeInto(scene, loads);
}

}  // namespace

bool IsMeshFile(const std::string& path) {
  const auto ext = std::filesystem::path(path).extension();
  return ext == ".msh" || ext == ".inp";
}

Json SceneOfMesh(const ImportedMesh& mesh, const Json& loads, const std::string& loads_name) {
  Json scene;
  scene["name"] = std::filesystem::path(mesh.source).stem().string();
  scene["description"] = "imported from " + std::filesystem::path(mesh.source).filename().string() +
                         ": " + std::to_string(mesh.nodes.size() / mesh.dimension) + " nodes, " +
                         std::to_string(mesh.elements.size()) +
                         (mesh.dimension == 2 ? " triangles" : " tetrahedra");
  Json nodes = Json::array();
  for (std::size_t i = 0; i < mesh.nodes.size(); i += mesh.dimension) {
    Json x = Json::array();
    for (int c = 0; c < mesh.dimension; ++c) x.push_back(mesh.nodes[i + c]);
    nodes.push_back(std::move(x));
  }
  scene["nodes"] = std::move(nodes);
  if (!mesh.node_sets.empty()) scene["node_sets"] = mesh.node_sets;
  scene["reference"] = {{"type", "fem"}, {"elements", mesh.elements}};

  MergeLoads(scene, loads, loads_name);
  ResolveRegionMaterials(scene["reference"], mesh, loads_name);
  return scene;
}

Json ImportSceneFiles(const std::vector<std::string>& paths, const std::string& loads_path) {
  Json loads;
  if (!loads_path.empty()) {
    try {
      loads = proto::ParseJson(proto::ReadFile(loads_path));
    } catch (const InputError& e) {
      throw InputError("", loads_path + ": " + e.what());
    }
  }
  if (std::all_of(paths.begin(), paths.end(), IsAbaqusDeck)) {
    Json scene = SceneOfAbaqusDecks(paths);
    MergeLoads(scene, loads, loads_path);
    return scene;
  }
  if (paths.size() == 1 && std::filesystem::path(paths[0]).extension() == ".msh")
    return SceneOfMesh(ReadGmshMesh(paths[0]), loads, loads_path);
  throw InputError(
      "", paths[0] + (paths.size() > 1 ? " ...: several files are decks (.inp) of one model"
                                       : ": not a mesh springfit reads (expected a Gmsh .msh or a "
                                         "CalculiX/Abaqus .inp deck)"));
}

}  // namespace springfit::io
