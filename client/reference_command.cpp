// springfit reference SCENE [--json] [-o FILE]: solve the scene's reference model and write
// its equilibrium positions per load case.
#include <cstdio>
#include <fstream>
#include <iostream>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/scene_input.h"
#include "engine/api/problem.h"
#include "proto/names.h"
#include "proto/reference_codec.h"
#include "proto/scene_codec.h"

namespace springfit::cli {
namespace {

struct ReferenceArgs {
  SceneInput scene;
  std::string output;
  bool json = false;
};

int Reference(const ReferenceArgs& args) {
  // Validated before the probe: a bad scene leaves no output file behind.
  ValidScene scene(SceneOf(args.scene));
  if (!args.output.empty()) {
    // Before the solve: a reference of 100,000 DOFs takes seconds.
    std::ofstream probe(args.output, std::ios::binary | std::ios::app);
    if (!probe) throw std::runtime_error("cannot write '" + args.output + "'");
  }
  const Problem problem(std::move(scene));
  const proto::Json out = proto::ReferenceSolutionToJson(problem);
  const std::string text = proto::DumpCompact(out);
  if (!args.output.empty()) {
    std::ofstream file(args.output, std::ios::binary | std::ios::trunc);
    file << text;
    if (!file.flush()) throw std::runtime_error("cannot write '" + args.output + "'");
  }
  if (args.json) {
    std::cout << text;
    return kExitOk;
  }
  const Scene& s = problem.scene();
  std::cout << "reference: " << proto::ReferenceKindName(s.reference.kind) << ", "
            << s.load_cases.size() << " load case" << (s.load_cases.size() == 1 ? "" : "s") << "\n";
  for (std::size_t k = 0; k < problem.load_cases().size(); ++k) {
    const proto::Json& c = out["solves"][k];
    std::printf("  [%zu] %s: largest displacement %.6g", k,
                s.load_cases[k].name.empty() ? "(unnamed)" : s.load_cases[k].name.c_str(),
                c["max_displacement"].get<double>());
    if (c.contains("iterations")) {
      const int iterations = c["iterations"].get<int>(), steps = c["load_steps"].get<int>();
      std::printf(", %d Newton iteration%s, %d load step%s, relative residual %.3g", iterations,
                  iterations == 1 ? "" : "s", steps, steps == 1 ? "" : "s",
                  c["residual"].get<double>());
    }
    const auto& solve = problem.load_cases()[k].reference_solve;
    if (solve && solve->resolution > kReferenceResolutionWarning)
      std::printf(", displacements determined only to %.2g of their size (round-off)",
                  solve->resolution);
    if (solve && !solve->stable) std::printf(", an unstable equilibrium");
    std::printf("\n");
  }
  std::fflush(stdout);
  if (!args.output.empty()) std::cout << "positions written to " << args.output << "\n";
  return kExitOk;
}

}  // namespace

void RegisterReference(CLI::App& app, int& exit_code) {
  auto* cmd = app.add_subcommand(
      "reference",
      "Solve the scene's reference model and write its equilibrium positions per load case");
  auto args = std::make_shared<ReferenceArgs>();
  AddSceneInput(cmd, args->scene);
  cmd->add_flag("--json", args->json,
                "Print the positions and solver statistics as JSON (proto/SCENE.md)");
  cmd->add_option("-o,--output", args->output, "Also write the JSON to this file");
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors(args->scene.path, [&] { return Reference(*args); });
  });
}

}  // namespace springfit::cli
