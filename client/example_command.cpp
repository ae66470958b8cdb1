// springfit example NAME [-o FILE]: write a built-in scene.
#include <fstream>
#include <iostream>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "engine/api/input_error.h"
#include "io/example_catalog.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace {

struct ExampleArgs {
  std::string name;
  std::string output;
  bool list = false;
  double noise = 0.0;
  std::uint64_t noise_seed = 1;
};

int Example(const ExampleArgs& args) {
  if (args.list || args.name.empty()) {
    for (const examples::ExampleInfo& e : examples::Catalog()) {
      std::cout << e.name << "\n    " << e.description << "\n";
    }
    return kExitOk;
  }
  Scene scene;
  try {
    scene = examples::Make(args.name);  // the catalogue itself would build every example
  } catch (const std::invalid_argument&) {
    throw InputError("NAME", "unknown example '" + args.name + "' (springfit example --list)");
  }
  if (args.noise > 0.0) scene = examples::WithMeasurementNoise(scene, args.noise, args.noise_seed);
  const std::string text = proto::DumpCompact(proto::SceneToJson(scene));
  if (args.output.empty() || args.output == "-") {
    std::cout << text;
    return kExitOk;
  }
  std::ofstream out(args.output, std::ios::binary);
  out << text;
  if (!out.flush()) throw std::runtime_error("cannot write '" + args.output + "'");
  return kExitOk;
}

}  // namespace

void RegisterExample(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand("example", "Write a built-in example scene (--list names them)");
  auto args = std::make_shared<ExampleArgs>();
  cmd->add_option("NAME", args->name, "Example name");
  cmd->add_option("-o,--output", args->output, "Output file (default: standard output)");
  cmd->add_flag("--list", args->list, "List the examples");
  cmd->add_option("--noise", args->noise,
                  "Replace the reference by its equilibrium positions with Gaussian noise of this "
                  "fraction of "
                  "each load case's RMS displacement (e.g. 0.001)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--noise-seed", args->noise_seed, "Seed of the noise (default 1)");
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors("example", [&] { return Example(*args); });
  });
}

}  // namespace springfit::cli
