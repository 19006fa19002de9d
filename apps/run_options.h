// What `run` and `run-unit` share: the mission options (recorded in a plan as given and read
// again by run-unit), the executor options of a planned job (docs/cluster.md) and handing a plan
// to its executor.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "areomap/map/error.h"
#include "areomap/pipeline/mission_run.h"
#include "areomap/pipeline/work_plan.h"
#include "cli_common.h"

namespace areomap::cli {

// The options of `areomap run` that set MissionRunOptions.
struct MissionRunArguments {
  MissionRunOptions run;
  bool no_craters = false;
  bool no_products = false;
  bool keep_coarse_points = false;
  bool no_leg_test = false;
  bool no_rock_variance_pass = false;
  MissionRunOptions Resolve() const;  // The flags applied.
};
void AddMissionRunOptions(CLI::App* command, MissionRunArguments* arguments);
// The options a plan recorded (ArgumentsGiven), read again; throws areomap::Error when they do
// not parse (a plan written by another version).
MissionRunOptions ParseMissionRunArguments(const std::vector<std::string>& arguments);

// A plan's recorded options (ArgumentsGiven) read again with the options `add` registers, into
// a fresh app; throws areomap::Error naming the `command` when they do not parse (a plan written
// by another version).
template <typename Args>
Args ParsePlanArguments(const std::vector<std::string>& arguments, void (*add)(CLI::App*, Args*),
                        const std::string& command) {
  CLI::App app("areomap " + command + " options");
  Args parsed;
  add(app.add_option_group("recorded"), &parsed);
  std::vector<std::string> reversed(arguments.rbegin(), arguments.rend());
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    throw Error("the plan's " + command + " options cannot be read (" + e.what() + ")");
  }
  return parsed;
}

// The options given on the command line among `group`'s, as words ("--posting", "0.2", ...).
std::vector<std::string> ArgumentsGiven(const CLI::App& group);

// --plan, --executor and their options (`run`, `craters` over many images).
struct ExecutorArguments {
  bool plan_only = false;
  std::string executor = "local";  // local | slurm | parallel
  std::string slurm_args;
  bool wait = false;
  std::string hosts;
  int jobs = 0;
  std::string parallel_args;
  double stale_after_s = 120.0;
};
void AddExecutorOptions(CLI::App* command, ExecutorArguments* arguments);

// After a plan is written to `dir`: prints where it is (--plan), submits it to Slurm, or runs it
// through GNU parallel. Returns true when the job finished here (parallel; slurm --wait).
// Throws areomap::Error from the executor (failed units named).
bool RunPlan(const std::filesystem::path& dir, const WorkPlan& plan,
             const ExecutorArguments& arguments, const GlobalOptions& global);

// The JSON in `path`; throws areomap::Error naming it when it is missing or malformed.
nlohmann::json ReadJsonFile(const std::filesystem::path& path);

}  // namespace areomap::cli
