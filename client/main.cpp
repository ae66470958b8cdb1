// springfit: identify mass-spring model topologies. Subcommands in client/*_command.cpp.
#include <iostream>

#include <CLI/CLI.hpp>

#include "client/commands.h"
#include "client/exit_codes.h"

int main(int argc, char** argv) {
  CLI::App app{"springfit: identify the topology of mass-spring models of soft tissue"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "springfit 0.3.0");
  int exit_code = springfit::cli::kExitOk;
  springfit::cli::RegisterCheck(app, exit_code);
  springfit::cli::RegisterEval(app, exit_code);
  springfit::cli::RegisterExample(app, exit_code);
  springfit::cli::RegisterReference(app, exit_code);
  springfit::cli::RegisterRun(app, exit_code);
  springfit::cli::RegisterSubmit(app, exit_code);
  springfit::cli::RegisterJobCommands(app, exit_code);
  springfit::cli::RegisterFigureCommands(app, exit_code);
  springfit::cli::RegisterExport(app, exit_code);
  springfit::cli::RegisterImport(app, exit_code);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return springfit::cli::kExitUsage;
  }
  return exit_code;
}
