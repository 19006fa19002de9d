// The command reference (docs/cli.md) generated from the CLI's own definitions: every command's
// description, its details (the subcommand's footer) and a table of its positionals and options
// with their types, defaults and help. `areomap cli-reference` prints it; a test keeps docs/cli.md
// equal to it.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

namespace areomap::cli {

// Markdown for `app` and its named subcommands, depth first in the order they were added.
std::string CliReferenceMarkdown(const CLI::App& app);

// Adds the hidden `cli-reference` command that prints CliReferenceMarkdown(app) to stdout.
void AddCliReferenceCommand(CLI::App& app);

}  // namespace areomap::cli
