// The subcommands of the `springfit` program. Each Register function adds its subcommand to
// the application and binds a callback that sets the exit code.
#pragma once

#include <CLI/CLI.hpp>

namespace springfit::cli {

void RegisterCheck(CLI::App& app, int& exit_code);
void RegisterEval(CLI::App& app, int& exit_code);
void RegisterExample(CLI::App& app, int& exit_code);
void RegisterReference(CLI::App& app, int& exit_code);
void RegisterRun(CLI::App& app, int& exit_code);
void RegisterSubmit(CLI::App& app, int& exit_code);
void RegisterJobCommands(
    CLI::App& app, int& exit_code);  // status, watch, result, trace, cancel, delete, list, info
void RegisterFigureCommands(CLI::App& app, int& exit_code);  // render, plot
void RegisterExport(CLI::App& app, int& exit_code);
void RegisterImport(CLI::App& app, int& exit_code);

}  // namespace springfit::cli
