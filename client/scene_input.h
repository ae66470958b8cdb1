// The scene a command is given: a scene file (JSON, proto/SCENE.md), or a mesh (.msh) with a
// loads file (`--loads`), imported (io/mesh_import.h, proto/IMPORT.md). run, submit, check,
// eval and reference accept both; the daemon only ever receives the resulting JSON scene.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "engine/api/scene.h"
#include "proto/json_reader.h"

namespace springfit::cli {

struct SceneInput {
  std::string path;
  std::string loads;  // empty: none
  // `import` only: further decks of the same model (their steps are more load cases), and
  // CalculiX results to use as a positions reference.
  std::vector<std::string> more;
  std::vector<std::string> results;
};

// SCENE (a scene file or a mesh) and --loads.
void AddSceneInput(CLI::App* command, SceneInput& input);

// The scene as JSON (a mesh imported, its loads merged). Throws InputError naming the file.
proto::Json SceneJsonOf(const SceneInput& input);
// The scene, validated (a scene file's errors keep their line and column).
Scene SceneOf(const SceneInput& input);
// The scene of `json`, which SceneJsonOf(input) gave, validated; errors name the input's files.
Scene SceneOfImported(const SceneInput& input, const proto::Json& json);

}  // namespace springfit::cli
