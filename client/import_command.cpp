// springfit import MESH [--loads LOADS.json] [-o SCENE.json]: a mesh made into a scene
// (io/mesh_import.h, proto/IMPORT.md).
#include <fstream>
#include <iostream>
#include <memory>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/scene_input.h"
#include "engine/api/input_error.h"
#include "engine/api/scene.h"
#include "io/mesh_import.h"

namespace springfit::cli {
namespace {

struct ImportArgs {
  SceneInput input;
  std::string output;
};

int Import(const ImportArgs& a) {
  const proto::Json json = SceneJsonOf(a.input);
  // With loads, or from decks (which carry their materials and steps), the scene is whole: it
  // is validated as `run` would read it.
  const bool whole =
      !a.input.loads.empty() || !io::IsMeshFile(a.input.path) || io::IsAbaqusDeck(a.input.path);
  if (whole) SceneOfImported(a.input, json);  // (the files are read once)
  const std::string text = json.dump(1) + "\n";
  if (a.output.empty()) {
    std::cout << text;
  } else {
    std::ofstream out(a.output, std::ios::binary);
    out << text;
    out.close();
    if (!out) throw std::runtime_error("cannot write " + a.output);
    const proto::Json& ref = json["reference"];
    std::cerr << a.output << ": " << json["nodes"].size() << " nodes, ";
    if (ref.contains("elements")) {
      std::cerr << ref["elements"].size() << " elements (reference fem)";
    } else if (ref.contains("springs")) {
      std::cerr << ref["springs"].size() << " springs (reference mss)";
    } else {
      std::cerr << "reference positions (" << ref.value("positions", proto::Json::array()).size()
                << " configurations)";
    }
    if (json.contains("node_sets")) {
      std::cerr << ", node sets:";
      for (const auto& [name, nodes] : json["node_sets"].items())
        std::cerr << " " << name << " (" << nodes.size() << ")";
    }
    if (json.contains("load_cases"))
      std::cerr << ", " << json["load_cases"].size() << " load cases";
    std::cerr << "\n";
  }
  if (!whole) {
    std::cerr << "note: without --loads the scene lacks a material and load cases "
                 "(proto/IMPORT.md)\n";
  }
  return kExitOk;
}

}  // namespace

void RegisterImport(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ImportArgs>();
  auto* cmd = app.add_subcommand(
      "import",
      "Make a scene of a mesh (Gmsh .msh) or CalculiX/Abaqus decks (.inp) and a loads file "
      "(proto/IMPORT.md)");
  AddSceneInput(cmd, args->input);
  cmd->add_option("MORE", args->input.more,
                  "Further CalculiX/Abaqus decks of the same model: their steps are more load "
                  "cases");
  cmd->add_option("--results", args->input.results,
                  "CalculiX results of the decks (.frd with *NODE FILE U, or .dat with *NODE "
                  "PRINT U; one step per load case, in order): the reference becomes those "
                  "positions")
      ->expected(1, -1);
  cmd->add_option("-o,--output", args->output, "The scene file to write (default: stdout)");
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors("import", [&] { return Import(*args); });
  });
}

}  // namespace springfit::cli
