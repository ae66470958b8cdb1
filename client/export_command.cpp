// springfit export RESULT_OR_ID -o FILE: the identified model in a simulator's or viewer's
// format, chosen by the file's extension (io/model_writers.h, proto/MODEL.md).
#include <iostream>
#include <memory>

#include "client/commands.h"
#include "client/error_reporting.h"
#include "client/exit_codes.h"
#include "client/remote_job.h"
#include "client/result_source.h"
#include "io/model_writers.h"
#include "io/spring_model.h"

namespace springfit::cli {
namespace {

struct ExportArgs {
  ServerOptions server;
  std::string source;
  std::string output;
  std::string scene_path;
};

int Export(const ExportArgs& a) {
  // The format first: an unknown extension is refused before anything is read or fetched.
  const io::ModelFormat format = io::ModelFormatOfPath(a.output);
  const ResultWithScene loaded = LoadResultWithScene(a.source, a.server, a.scene_path);
  const io::SpringModel model = io::ModelOfResult(*loaded.problem, loaded.result);
  io::WriteModelFile(model, a.output);
  int undetermined = 0;
  for (const auto& s : model.springs) undetermined += s.identified ? 0 : 1;
  std::cout << a.output << ": " << io::ModelFormatName(format) << ", " << model.node_count()
            << " nodes, " << model.springs.size() << " springs";
  if (undetermined > 0) std::cout << " (" << undetermined << " not determined by the data)";
  std::cout << ", from " << loaded.where << "\n";
  return kExitOk;
}

}  // namespace

void RegisterExport(CLI::App& app, int& exit_code) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand(
      "export",
      "Write the identified model for a simulator or viewer: .vtk, .vtu (ParaView), .msh "
      "(Gmsh), .scn (SOFA) or .json, by the output's extension (proto/MODEL.md)");
  cmd->add_option("RESULT_OR_ID", args->source, "A result file (run -o, result -o) or a job id")
      ->required();
  cmd->add_option("-o,--output", args->output, "The model file to write")->required();
  cmd->add_option("--scene", args->scene_path,
                  "The scene, for a result file that does not carry it");
  AddServerFlags(cmd, args->server);
  cmd->callback([args, &exit_code] {
    exit_code = RunReportingErrors("export", [&] { return Export(*args); });
  });
}

}  // namespace springfit::cli
