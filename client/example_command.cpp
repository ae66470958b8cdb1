// springfit example NAME [-o FILE]: write a built-in scene.
#include <fstream>
#include <iostream>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "engine/examples/catalog.h"
#include "engine/input_error.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace {

struct ExampleArgs {
  std::string name;
  std::string output;
  bool list = false;
};

int Example(const ExampleArgs& args) {
  if (args.list || args.name.empty()) {
    for (const examples::ExampleInfo& e : examples::Catalog()) {
      std::cout << e.name << "\n    " << e.description << "\n";
    }
    return kExitOk;
  }
  bool known = false;
  for (const examples::ExampleInfo& e : examples::Catalog()) known = known || e.name == args.name;
  if (!known) throw InputError("NAME", "unknown example '" + args.name + "' (springfit example --list)");
  const std::string text = proto::DumpCompact(proto::SceneToJson(examples::Make(args.name)));
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
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors("example", [&] { return Example(*args); });
  });
}

}  // namespace springfit::cli
