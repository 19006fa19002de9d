// areomap: Mars orbital-ground registration and mapping. One binary, one subcommand per job.
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>

#include <glog/logging.h>
#include <CLI/CLI.hpp>

#include "areomap/map/error.h"
#include "cli_reference.h"
#include "commands.h"

namespace {

// When parsing stopped because a command that takes a subcommand (areomap itself, rocks, camera,
// errors) got a word that names none of its subcommands: "unknown subcommand 'WORD'; expected
// one of: ...". Empty otherwise (CLI11's own message then says what went wrong).
std::string UnknownSubcommandMessage(const CLI::App& app) {
  const CLI::App* leaf = &app;  // The last subcommand parsed.
  while (!leaf->get_subcommands().empty()) leaf = leaf->get_subcommands().back();
  if (leaf->get_require_subcommand_min() == 0) return {};
  // Unmatched words fall through to the top (app.fallthrough()).
  std::string word;
  for (const std::string& arg : app.remaining(true)) {
    if (!arg.empty() && arg.front() != '-') {
      word = arg;
      break;
    }
  }
  if (word.empty()) return {};
  std::string names;
  // Option groups are unnamed subcommands.
  for (const CLI::App* sub :
       leaf->get_subcommands([](const CLI::App* a) { return !a->get_name().empty(); })) {
    names += (names.empty() ? "" : ", ") + sub->get_name();
  }
  return "unknown subcommand '" + word + "'" +
         (leaf == &app ? std::string() : " of " + leaf->get_name()) + "; expected one of: " + names;
}

}  // namespace

int main(int argc, char** argv) {
  // Ceres logs through glog (a failed crater fit, a rank-deficient Jacobian in the adjustment);
  // the commands report what matters in their summaries, so only fatal glog messages reach stderr.
  FLAGS_minloglevel = google::GLOG_FATAL;
  CLI::App app{"areomap: register Mars rover data to orbital data and make maps from both",
               "areomap"};
  app.set_version_flag("--version", std::string("areomap ") + AREOMAP_VERSION);
  app.require_subcommand(1);
  app.fallthrough();  // Global options (--quiet) may follow the subcommand.
  areomap::cli::GlobalOptions global;
  app.add_flag("--quiet", global.quiet, "No progress bar and no human summary");
  app.add_flag("--overwrite", global.overwrite,
               "Replace files in --out that carry an output's name but that no areomap command "
               "recorded writing there (.areomap-outputs.json); a command's own earlier outputs "
               "are replaced without it");
  areomap::cli::AddInfoCommand(app, global);
  areomap::cli::AddCoordsCommand(app, global);
  areomap::cli::AddCameraCommand(app, global);
  areomap::cli::AddSampleCommand(app, global);
  areomap::cli::AddSimulateCommand(app, global);
  areomap::cli::AddStereoCommand(app, global);
  areomap::cli::AddErrorsCommand(app, global);
  areomap::cli::AddAdjustCommand(app, global);
  areomap::cli::AddRunCommand(app, global);
  areomap::cli::AddRunUnitCommands(app, global);
  areomap::cli::AddDtmCommand(app, global);
  areomap::cli::AddCratersCommand(app, global);
  areomap::cli::AddRegisterCommand(app, global);
  areomap::cli::AddOrthoCommand(app, global);
  areomap::cli::AddMosaicCommand(app, global);
  areomap::cli::AddRocksCommand(app, global);
  areomap::cli::AddCliReferenceCommand(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::RuntimeError& e) {
    return e.get_exit_code();  // The command reported its own failures (e.g. coords lines).
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == static_cast<int>(CLI::ExitCodes::Success)) return app.exit(e);
    const std::string unknown = UnknownSubcommandMessage(app);
    std::fprintf(stderr, "error: %s\nRun with --help for more information.\n",
                 unknown.empty() ? e.what() : unknown.c_str());
    return e.get_exit_code();
  } catch (const areomap::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: internal: %s\n", e.what());
    return 2;
  }
  return 0;
}
