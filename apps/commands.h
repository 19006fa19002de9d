// Registration of the subcommands on the CLI11 application. Each command parses its options
// into the library's option structs and calls one library function.
#pragma once

#include <CLI/CLI.hpp>

#include "cli_common.h"

namespace areomap::cli {

void AddInfoCommand(CLI::App& app, const GlobalOptions& global);
void AddCoordsCommand(CLI::App& app, const GlobalOptions& global);
void AddCameraCommand(CLI::App& app, const GlobalOptions& global);
void AddSampleCommand(CLI::App& app, const GlobalOptions& global);
void AddSimulateCommand(CLI::App& app, const GlobalOptions& global);
void AddStereoCommand(CLI::App& app, const GlobalOptions& global);
void AddErrorsCommand(CLI::App& app, const GlobalOptions& global);
void AddAdjustCommand(CLI::App& app, const GlobalOptions& global);
void AddRunCommand(CLI::App& app, const GlobalOptions& global);
void AddRunUnitCommands(CLI::App& app, const GlobalOptions& global);  // run-unit, run-status
void AddDtmCommand(CLI::App& app, const GlobalOptions& global);
void AddCratersCommand(CLI::App& app, const GlobalOptions& global);
void AddRegisterCommand(CLI::App& app, const GlobalOptions& global);
void AddOrthoCommand(CLI::App& app, const GlobalOptions& global);
void AddMosaicCommand(CLI::App& app, const GlobalOptions& global);
void AddRocksCommand(CLI::App& app, const GlobalOptions& global);

}  // namespace areomap::cli
