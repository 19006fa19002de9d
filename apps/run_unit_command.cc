// areomap run-unit DIR UNIT... and areomap run-status DIR: the units of a plan (work_plan.h,
// docs/cluster.md) run one process at a time on any host that sees DIR, and their state.
#include <cstdio>
#include <cstdlib>
#include <map>

#include "areomap/map/error.h"
#include "areomap/pipeline/catalogue_plan.h"
#include "areomap/pipeline/executors.h"
#include "areomap/pipeline/mission_plan.h"
#include "commands.h"
#include "craters_args.h"
#include "run_options.h"

namespace areomap::cli {
namespace {

namespace fs = std::filesystem;

constexpr const char* kRunUnitDetails =
    "Runs units of the plan in DIR/plan.json (written by `areomap run ... --plan` or `areomap\n"
    "craters IMAGE... --plan`) in the order given: by id (`areomap run-status DIR` lists them),\n"
    "or the one at --task-index in --stage (a Slurm array task). Safe to run in many processes\n"
    "on many hosts at once over a shared filesystem: each unit is claimed\n"
    "(DIR/.areomap-units/ID.claim, kept fresh by a heartbeat); a unit already done with the\n"
    "plan's fingerprint is skipped; a unit another live process holds is waited for; a claim\n"
    "whose holder died (on this host at once, elsewhere after --stale-after seconds) is taken\n"
    "over. A unit that fails writes error.txt in its folder and the next named units still run;\n"
    "the command then exits non-zero naming the failed units (docs/cluster.md).";

constexpr const char* kRunStatusDetails =
    "Counts a plan's units per stage as done, running (a live claim: host, pid), failed\n"
    "(error.txt in the unit's folder) or pending, and lists the running and failed ones.";

void PrintRecords(const std::vector<UnitRunRecord>& records) {
  for (const UnitRunRecord& r : records) {
    std::printf("%s: %s (%.1f s)%s%s\n", r.id.c_str(), ToString(r.outcome), r.seconds,
                r.error.empty() ? "" : ": ", r.error.c_str());
  }
}

void PrintStatus(const fs::path& dir, const WorkPlan& plan, const std::vector<UnitStatus>& status) {
  std::printf("plan: %s (job %s, %zu units)\n", (dir / kPlanFileName).c_str(), plan.job.c_str(),
              plan.UnitCount());
  std::printf("%-18s %6s %8s %7s %8s\n", "stage", "done", "running", "failed", "pending");
  for (const PlannedStage& stage : plan.stages) {
    std::map<UnitState, int> count;
    for (const UnitStatus& s : status) {
      if (s.stage == stage.name) ++count[s.state];
    }
    std::printf("%-18s %6d %8d %7d %8d\n", stage.name.c_str(), count[UnitState::kDone],
                count[UnitState::kRunning], count[UnitState::kFailed], count[UnitState::kPending]);
  }
  for (const UnitStatus& s : status) {
    if (s.state == UnitState::kRunning || s.state == UnitState::kFailed || !s.detail.empty()) {
      std::printf("%s %s: %s\n", ToString(s.state), s.id.c_str(), s.detail.c_str());
    }
  }
}

struct RunUnitOptions {
  std::string dir;
  std::vector<std::string> units;
  std::string stage;
  int task_index = -1;
  UnitClaimOptions claims;
};

void AddRunUnitOptions(CLI::App* unit, RunUnitOptions& o) {
  unit->add_option("DIR", o.dir, "The folder holding plan.json")->required();
  unit->add_option("UNIT", o.units, "Unit ids, e.g. site_003 leg_003_004 finish");
  unit->add_option("--stage", o.stage, "With --task-index: the stage whose unit to run");
  unit->add_option("--task-index", o.task_index,
                   "The unit at this index (from 0) in --stage, e.g. $SLURM_ARRAY_TASK_ID")
      ->check(CLI::NonNegativeNumber);
  unit->add_option("--stale-after", o.claims.stale_after_s,
                   "A claim untouched this long is taken over [s]")
      ->check(CLI::Range(20.0, 86400.0))
      ->capture_default_str();
}

// The units named, then the one at --task-index in --stage.
std::vector<std::string> UnitIdsToRun(const RunUnitOptions& o, const WorkPlan& plan) {
  std::vector<std::string> ids = o.units;
  if (!o.stage.empty() || o.task_index >= 0) {
    if (o.stage.empty() || o.task_index < 0) {
      throw Error("--stage and --task-index go together");
    }
    const PlannedStage& stage = plan.Stage(o.stage);
    if (static_cast<size_t>(o.task_index) >= stage.units.size()) {
      throw Error("--task-index " + std::to_string(o.task_index) + ": stage " + stage.name +
                  " has " + std::to_string(stage.units.size()) + " units (0 to " +
                  std::to_string(stage.units.size() - 1) + ")");
    }
    ids.push_back(stage.units[o.task_index].id);
  }
  if (ids.empty()) throw Error("name the units to run, or --stage and --task-index");
  return ids;
}

// Runs `ids` with the job the plan names (a mission run or a crater catalogue).
std::vector<UnitRunRecord> RunPlanUnits(const RunUnitOptions& o, const WorkPlan& plan,
                                        const std::vector<std::string>& ids,
                                        const GlobalOptions& global) {
  if (plan.job == "run") {
    return RunMissionPlanUnits(o.dir, plan, ParseMissionRunArguments(plan.arguments), ids, o.claims,
                               MakeProgressBar(global, "run-unit"));
  }
  if (plan.job == "craters") {
    const CratersArgs args = ParseCratersArguments(plan.arguments);
    CatalogueMergeOptions merge;
    merge.crs = args.crs;
    return RunCataloguePlanUnits(o.dir, plan, ImageOptions(args), merge, CatalogueSummaryHead(args),
                                 ids, o.claims, MakeProgressBar(global, "run-unit"));
  }
  throw Error((fs::path(o.dir) / kPlanFileName).string() + ": unknown job \"" + plan.job +
              "\" (expected run or craters)");
}

void RunRunUnitCommand(const RunUnitOptions& o, const GlobalOptions& global) {
  const WorkPlan plan = ReadWorkPlan(o.dir);
  const std::vector<std::string> ids = UnitIdsToRun(o, plan);
  const std::vector<UnitRunRecord> records = RunPlanUnits(o, plan, ids, global);
  if (!global.quiet) PrintRecords(records);
  std::string failed;
  for (const UnitRunRecord& r : records) {
    if (r.outcome == UnitOutcome::kFailed) failed += (failed.empty() ? "" : ", ") + r.id;
  }
  if (!failed.empty()) {
    throw Error("units failed: " + failed + " (error.txt in their folders)");
  }
}

struct RunStatusOptions {
  std::string dir;
  bool json = false;  // --json: the units' states as JSON.
};

void RunRunStatusCommand(const RunStatusOptions& o) {
  const WorkPlan plan = ReadWorkPlan(o.dir);
  const std::vector<UnitStatus> units = ReadPlanStatus(o.dir, plan);
  if (o.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const UnitStatus& s : units) {
      out.push_back(
          {{"stage", s.stage}, {"unit", s.id}, {"state", ToString(s.state)}, {"detail", s.detail}});
    }
    std::printf("%s\n", out.dump(2).c_str());
  } else {
    PrintStatus(o.dir, plan, units);
  }
}

}  // namespace

void AddRunUnitCommands(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<RunUnitOptions>();
  auto* unit = app.add_subcommand("run-unit", "Runs units of a planned job (docs/cluster.md)");
  unit->footer(kRunUnitDetails);
  AddRunUnitOptions(unit, *o);
  unit->callback([o, &global] { RunRunUnitCommand(*o, global); });

  auto status_options = std::make_shared<RunStatusOptions>();
  auto* status = app.add_subcommand("run-status", "The state of a planned job's units");
  status->footer(kRunStatusDetails);
  status->add_option("DIR", status_options->dir, "The folder holding plan.json")->required();
  status->add_flag("--json", status_options->json, "Print the units' states as JSON");
  status->callback([status_options] { RunRunStatusCommand(*status_options); });
}

}  // namespace areomap::cli
