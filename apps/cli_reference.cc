#include "cli_reference.h"

#include <cstdio>
#include <sstream>
#include <vector>

namespace areomap::cli {
namespace {

// A table cell: pipes escaped, newlines as spaces.
std::string Cell(std::string text) {
  std::string out;
  for (const char c : text) {
    if (c == '|') {
      out += "\\|";
    } else if (c == '\n') {
      out += ' ';
    } else {
      out += c;
    }
  }
  return out;
}

// The option as a user types it: `--out DIR`, `-h,--help`, or a positional's name.
std::string OptionName(const CLI::Option& option) {
  std::string name = option.nonpositional() ? option.get_name(false, true) : option.get_name(true);
  const std::string type = option.get_type_name();
  if (option.nonpositional() && option.get_type_size() != 0 && !type.empty()) {
    name += " " + type;
  }
  return name;
}

// A subcommand inherits its parent's footer (CLI11): printed once, with the parent.
// The options `command` shows in its help: its own, then those of its option groups (unnamed
// sub-apps, e.g. run's "Mission options"), in the order they were added.
void AppendOptions(const CLI::App& command, std::vector<const CLI::Option*>& options) {
  for (const CLI::Option* o :
       command.get_options([](const CLI::Option* o) { return !o->get_group().empty(); })) {
    options.push_back(o);
  }
  for (const CLI::App* group :
       command.get_subcommands([](const CLI::App* a) { return a->get_name().empty(); })) {
    AppendOptions(*group, options);
  }
}

void AppendCommand(const CLI::App& command, const std::string& path, std::ostringstream& out) {
  out << "## `" << path << "`\n\n";
  const std::string& description = command.get_description();
  if (!description.empty()) {
    out << description << (description.back() == '.' ? "" : ".") << "\n\n";
  }
  const CLI::App* parent = command.get_parent();
  if (!command.get_footer().empty() &&
      (parent == nullptr || parent->get_footer() != command.get_footer())) {
    out << command.get_footer() << "\n\n";
  }
  std::vector<const CLI::Option*> options;
  AppendOptions(command, options);
  if (!options.empty()) {
    out << "| argument | meaning | default |\n|---|---|---|\n";
    for (const CLI::Option* option : options) {
      std::string meaning = option->get_description();
      if (option->get_required()) meaning += " (required)";
      out << "| `" << Cell(OptionName(*option)) << "` | " << Cell(meaning) << " | "
          << (option->get_default_str().empty() ? "" : "`" + Cell(option->get_default_str()) + "`")
          << " |\n";
    }
    out << "\n";
  }
  for (const CLI::App* sub :
       command.get_subcommands([](const CLI::App* a) { return !a->get_group().empty(); })) {
    if (sub->get_name().empty()) continue;  // An option group, not a command.
    AppendCommand(*sub, path + " " + sub->get_name(), out);
  }
}

}  // namespace

std::string CliReferenceMarkdown(const CLI::App& app) {
  std::ostringstream out;
  out << "# Command reference\n\n"
      << "Generated from the CLI's own definitions by `areomap cli-reference > docs/cli.md` (a "
         "test keeps it up to date). The README has one line per command; `areomap COMMAND "
         "--help` prints the same as its section here.\n\n";
  AppendCommand(app, app.get_name(), out);
  return out.str();
}

void AddCliReferenceCommand(CLI::App& app) {
  auto* command = app.add_subcommand("cli-reference", "Prints the command reference (Markdown)");
  command->group("");  // Hidden: a maintainer's tool, not a user's command.
  command->callback([&app] { std::fputs(CliReferenceMarkdown(app).c_str(), stdout); });
}

}  // namespace areomap::cli
