// A job cut into units for many processes on many hosts (docs/cluster.md): DIR/plan.json, the
// units' claims and their state. `areomap run ... --plan` and `areomap craters IMAGE... --plan`
// write a plan; `areomap run-unit DIR UNIT...` runs units of it; `areomap run-status DIR` reads
// their state; executors (executors.h) hand its stages to Slurm or GNU parallel.
//
// Layout under DIR (a shared filesystem when units run on several hosts):
//   plan.json                  the plan (WorkPlan::ToJson, format "areomap-plan" version 1)
//   .areomap-units/ID.claim    a unit's claim while a process runs it (unit_claim.h)
//   .areomap-units/ID.done     for units without a unit.json of their own: the fingerprint
//   <unit folder>/error.txt    why the unit's last attempt failed (removed when it succeeds)
// Stages run in plan order; a stage's units are independent of each other and start once every
// unit named in their "after" lists is done. Paths in a plan are absolute.
// Failure: reading a missing or malformed plan throws areomap::Error naming the file and field.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/output_folder.h"

namespace areomap {

struct PlannedUnit {
  std::string id;                  // Unique in the plan, [a-z0-9_]: "site_003", "finish".
  std::string folder;              // Where its products and error.txt go, relative to DIR.
  std::vector<std::string> after;  // Units that must be done before it starts.
  std::string description;         // What it does, for a person reading the plan.
};

struct PlannedStage {
  std::string name;                // "sites", "legs", ...
  std::vector<std::string> after;  // Stages whose units some of its units wait for.
  std::vector<PlannedUnit> units;
  // Its units start once those they wait for have ended, done or failed (a catalogue's merge
  // keeps the images that failed as rows); false: only once they are done.
  bool tolerates_failures = false;
};

struct WorkPlan {
  std::string job;                     // The command that made it: "run" or "craters".
  std::vector<std::string> inputs;     // The job's inputs (mission folder, images), absolute.
  std::vector<std::string> arguments;  // The command's options, re-read by run-unit.
  std::string fingerprint;             // Inputs + options; a unit's record must carry it.
  std::vector<PlannedStage> stages;

  size_t UnitCount() const;
  // The unit named `id`, and its stage; throws areomap::Error listing the plan's stages when
  // there is none.
  const PlannedUnit& Unit(const std::string& id, const PlannedStage** stage = nullptr) const;
  const PlannedStage& Stage(const std::string& name) const;  // Throws as Unit does.

  nlohmann::json ToJson() const;
  // Throws areomap::Error naming `source` and the field.
  static WorkPlan FromJson(const nlohmann::json& json, const std::string& source);
};

constexpr const char* kPlanFileName = "plan.json";
constexpr const char* kUnitsFolderName = ".areomap-units";

// DIR/plan.json, written atomically / read. ReadWorkPlan throws areomap::Error naming the file
// (and saying how to make one) when it is missing or malformed.
void WriteWorkPlan(const std::filesystem::path& dir, const WorkPlan& plan);
WorkPlan ReadWorkPlan(const std::filesystem::path& dir);

// Writes `plan` as DIR/plan.json under the output-folder `policy` (output_folder.h: the folder's
// checks, its lock, the record of its outputs) and returns it. The same plan already there is
// returned as it is, without taking the folder (a second executor started on the plan: taking it
// would remove the temporaries of units running elsewhere); when another process holds the
// folder, waits up to 10 s for it to write the same plan (two executors started at once).
// Throws areomap::Error from the policy.
WorkPlan WritePlanInFolder(const std::filesystem::path& dir, const WorkPlan& plan,
                           const OutputFolderOptions& policy);

std::filesystem::path ClaimFile(const std::filesystem::path& dir, const std::string& unit_id);
std::filesystem::path DoneFile(const std::filesystem::path& dir, const std::string& unit_id);
std::filesystem::path ErrorFile(const std::filesystem::path& dir, const PlannedUnit& unit);

// The identity of input files: the path (relative to `root` when given), size and modification
// time of each, hashed (FNV-1a, 64 bits, hex). A changed input changes it. Size and time rather
// than content, as make does: a stat per file, even for gigabytes of images.
std::string FilesIdentity(const std::vector<std::filesystem::path>& files,
                          const std::filesystem::path& root = {});

// Units without a unit.json of their own (whole-job steps) record being done in DoneFile.
bool DoneFileMatches(const std::filesystem::path& dir, const std::string& unit_id,
                     const std::string& fingerprint);
void WriteDoneFile(const std::filesystem::path& dir, const std::string& unit_id,
                   const std::string& fingerprint);

}  // namespace areomap
