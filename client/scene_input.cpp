#include "client/scene_input.h"

#include <cstdio>

#include "engine/api/input_error.h"
#include "engine/api/problem.h"
#include "io/mesh_import.h"
#include "proto/scene_codec.h"

namespace springfit::cli {

void AddSceneInput(CLI::App* command, SceneInput& input) {
  command
      ->add_option("SCENE", input.path,
                   "Scene file (JSON, proto/SCENE.md), or a mesh (Gmsh .msh, CalculiX/Abaqus "
                   ".inp) with --loads (proto/IMPORT.md)")
      ->required();
  command->add_option("--loads", input.loads,
                      "With a mesh: the rest of the scene (material, load cases on the mesh's "
                      "named groups, search settings), merged over it (proto/IMPORT.md)");
}

proto::Json SceneJsonOf(const SceneInput& input) {
  if (io::IsMeshFile(input.path)) {
    std::vector<std::string> paths{input.path};
    paths.insert(paths.end(), input.more.begin(), input.more.end());
    // What the import leaves out or reads differently from ccx, on stderr: every command that
    // takes a mesh or deck (import, run, submit, check, ...) says it alike.
    std::vector<std::string> notes;
    proto::Json scene = io::ImportSceneFiles(paths, input.loads, input.results, &notes);
    for (const std::string& note : notes)
      std::fprintf(stderr, "springfit: note: %s\n", note.c_str());
    return scene;
  }
  if (!input.loads.empty()) {
    throw InputError("", "--loads applies to a mesh (.msh); " + input.path + " is a scene");
  }
  if (!input.more.empty() || !input.results.empty()) {
    throw InputError("", "further decks and --results apply to CalculiX/Abaqus decks (.inp); " +
                             input.path + " is a scene");
  }
  proto::Json scene = proto::ParseJson(proto::ReadFile(input.path));
  if (!scene.is_object()) throw InputError("", "a scene is a JSON object (proto/SCENE.md)");
  return scene;
}

Scene SceneOf(const SceneInput& input) {
  if (!io::IsMeshFile(input.path)) {
    if (!input.loads.empty()) {
      throw InputError("", "--loads applies to a mesh (.msh); " + input.path + " is a scene");
    }
    return proto::LoadSceneFile(input.path);
  }
  return SceneOfImported(input, SceneJsonOf(input));
}

namespace {

// Whether an error at `path` of an imported scene lies in what the mesh gave (its nodes and
// elements, and their tags), not in what the loads file gave.
bool FromTheMesh(const std::string& path) {
  for (const char* field : {"nodes", "node_tags", "reference.elements", "reference.element_tags"})
    if (path.rfind(field, 0) == 0) return true;
  return false;
}

}  // namespace

// The scene a mesh and its loads make, validated as `run` reads it (proto/IMPORT.md), with the
// loads file named in the errors of what it gave.
Scene SceneOfImported(const SceneInput& input, const proto::Json& json) {
  try {
    return ValidScene(proto::SceneFromJson(json)).Release();
  } catch (const InputError& e) {
    // (The caller names the mesh; the loads file is named here, the field in both.)
    if (input.loads.empty()) {
      if (e.path() == "load_cases")
        throw InputError("load_cases",
                         "required: a mesh carries no load cases; pass them with --loads "
                         "LOADS.json (material, fixed node sets and loads on the mesh's physical "
                         "groups: proto/IMPORT.md)");
      throw;
    }
    if (FromTheMesh(e.path())) throw;  // (the caller names the mesh)
    throw InputError("", input.loads + " (over " + input.path + "): " + e.what());
  }
}

}  // namespace springfit::cli
