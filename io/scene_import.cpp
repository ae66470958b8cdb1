// A mesh made into a scene, and a loads file merged over it (mesh_import.h, proto/IMPORT.md).
#include <algorithm>
#include <filesystem>
#include <set>

#include "engine/api/input_error.h"
#include "io/mesh_import.h"
#include "io/text_output.h"
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
const char* const kLoadsFields[] = {"name",       "description", "reference",
                                    "candidates", "load_cases",  "stiffness",
                                    "search",     "node_sets",   "units"};

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
                       "node_sets, units; the mesh gives the nodes)");
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
    for (const char* key : {"elements", "element_tags"}) {
      if (r.contains(key))
        throw LoadsError(where, std::string("reference.") + key, "the mesh gives the elements");
    }
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

// The reference replaced by the results' positions (one step per load case, in order); the
// candidates are the elements' edges (a positions reference has no mesh of its own).
void UseResults(Json& scene, const std::vector<long>& ids, const std::vector<std::string>& files) {
  std::vector<std::pair<std::string, std::map<long, std::array<double, 3>>>> steps;
  for (const std::string& f : files) {
    for (auto& s : ReadCalculixDisplacements(f)) steps.emplace_back(f, std::move(s));
  }
  const Json& cases = scene["load_cases"];
  if (steps.size() != cases.size()) {
    throw InputError("", "--results: " + std::to_string(steps.size()) + " steps of results for " +
                             std::to_string(cases.size()) +
                             " load cases (one per *STEP of the decks, in order)");
  }
  const Json& nodes = scene["nodes"];
  Json positions = Json::array();
  for (std::size_t k = 0; k < steps.size(); ++k) {
    Json configuration = Json::array();
    for (std::size_t i = 0; i < ids.size(); ++i) {
      const auto it = steps[k].second.find(ids[i]);
      if (it == steps[k].second.end()) {
        throw InputError("", steps[k].first + ": no displacement of node " +
                                 std::to_string(ids[i]) +
                                 " (the results must cover every node "
                                 "of the elements)");
      }
      Json x = Json::array();
      for (std::size_t c = 0; c < nodes[i].size(); ++c)
        x.push_back(nodes[i][c].get<double>() + it->second[c]);
      configuration.push_back(std::move(x));
    }
    positions.push_back(std::move(configuration));
  }
  // The candidates: every edge of the elements (or the springs of a truss model).
  std::set<std::pair<int, int>> edges;
  const Json& reference = scene["reference"];
  const Json& cells = reference.contains("elements") ? reference["elements"] : reference["springs"];
  for (const Json& cell : cells) {
    for (std::size_t a = 0; a < cell.size(); ++a) {
      for (std::size_t b = a + 1; b < cell.size(); ++b) {
        const int p = cell[a].get<int>(), q = cell[b].get<int>();
        edges.emplace(std::min(p, q), std::max(p, q));
      }
    }
  }
  Json pairs = Json::array();
  for (const auto& [p, q] : edges) pairs.push_back({p, q});
  scene["candidates"] = {{"type", "pairs"}, {"pairs", std::move(pairs)}};
  // Results of a linear material are a linear response: the springs' is compared at rest too
  // (a nonlinear spring model against them mixes the springs' own geometric nonlinearity into
  // the error: E 0.80 against 0.046 on the kidney's decks).
  // (Compared as JSON: no string is extracted, which GCC's null-dereference analysis
  // misreads.)
  const auto is_linear = [](const Json& m) {
    return m.is_object() && m.contains("model") && m["model"] == Json("linear");
  };
  bool linear = false;
  if (reference.contains("material")) {
    linear = is_linear(reference["material"]);
  } else if (reference.contains("materials")) {
    linear = std::all_of(reference["materials"].begin(), reference["materials"].end(), is_linear);
  }
  scene["reference"] = {{"type", "positions"}, {"positions", std::move(positions)}};
  // An FEM model's answers: per-spring stiffness on the mesh's edges is what reproduces them
  // (strategy continuous; default's hybrid, one stiffness for every spring, ended at E 1.9
  // after 30 s on a user's lobe). A strategy or response the loads file names stands.
  Json& search = scene["search"];
  if (search.is_null()) search = Json::object();
  if (!search.contains("strategy")) search["strategy"] = "continuous";
  if (linear && !search.contains("response")) search["response"] = "linear";
}

}  // namespace

bool IsMeshFile(const std::string& path) {
  const std::string ext = LowerExtension(path);
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
  scene["node_tags"] = mesh.node_tags;
  if (!mesh.node_sets.empty()) scene["node_sets"] = mesh.node_sets;
  scene["reference"] = {
      {"type", "fem"}, {"elements", mesh.elements}, {"element_tags", mesh.element_tags}};

  MergeLoads(scene, loads, loads_name);
  ResolveRegionMaterials(scene["reference"], mesh, loads_name);
  return scene;
}

Json ImportSceneFiles(const std::vector<std::string>& paths, const std::string& loads_path,
                      const std::vector<std::string>& results, std::vector<std::string>* notes) {
  Json loads;
  if (!loads_path.empty()) {
    try {
      loads = proto::ParseJson(proto::ReadFile(loads_path));
    } catch (const InputError& e) {
      throw InputError("", loads_path + ": " + e.what());
    }
  }
  if (std::all_of(paths.begin(), paths.end(), IsAbaqusDeck)) {
    DeckImport deck;
    Json scene = SceneOfAbaqusDecks(paths, &deck);
    if (notes) notes->insert(notes->end(), deck.notes.begin(), deck.notes.end());
    if (!results.empty()) UseResults(scene, deck.node_ids, results);
    const bool fem = scene["reference"]["type"] == Json("fem");
    MergeLoads(scene, loads, loads_path);
    // What a deck as Gmsh writes it lacks (no sections, no steps) must come from --loads.
    const std::string from_loads =
        loads_path.empty() ? "pass --loads LOADS.json with it" : "give it in " + loads_path;
    if (!deck.has_steps && !scene.contains("load_cases")) {
      throw InputError("", paths[0] + ": no *STEP (each step is a load case), and no load_cases: " +
                               from_loads + " (proto/IMPORT.md)");
    }
    if (fem && !deck.has_sections) {
      Json& reference = scene["reference"];
      if (reference["type"] == Json("fem")) {
        ImportedMesh regions;
        regions.source = paths[0];
        regions.dimension = static_cast<int>(scene["nodes"][0].size());
        regions.element_regions = deck.element_regions;
        regions.region_elements = deck.region_elements;
        ResolveRegionMaterials(reference, regions, loads_path);
        if (!reference.contains("material") && !reference.contains("materials")) {
          std::string names;
          for (const auto& [name, n] : deck.region_elements)
            names += (names.empty() ? "" : ", ") + name;
          throw InputError(
              "", paths[0] + ": no *SOLID SECTION (the elements' material): " + from_loads +
                      " as reference.material" +
                      (names.empty() ? std::string()
                                     : ", or reference.materials by region (" + names + ")"));
        }
      }
    }
    return scene;
  }
  if (!results.empty()) {
    throw InputError("",
                     "--results needs the decks (.inp) the results were computed from: their "
                     "node ids name the results' nodes");
  }
  if (paths.size() == 1 && LowerExtension(paths[0]) == ".msh")
    return SceneOfMesh(ReadGmshMesh(paths[0]), loads, loads_path);
  throw InputError(
      "", paths[0] + (paths.size() > 1 ? " ...: several files are decks (.inp) of one model"
                                       : ": not a mesh springfit reads (expected a Gmsh .msh or a "
                                         "CalculiX/Abaqus .inp deck)"));
}

}  // namespace springfit::io
