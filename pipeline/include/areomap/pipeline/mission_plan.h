// The mission run (mission_run.h) as a plan for many processes on many hosts (work_plan.h,
// docs/cluster.md): `areomap run MISSION --out DIR --plan` writes it, `areomap run-unit DIR
// UNIT...` runs its units, an executor (executors.h) hands its stages to Slurm or GNU parallel.
//
// Stages and units (ids):
//   sites             site_NNN: stereo, DTM, orthophoto, registration of one site
//   legs              leg_NNN_MMM: the first pass of one leg, after its two sites
//   legs_second_pass  leg_NNN_MMM_pass2: the leg matched again with the variance factor pooled
//                     over every leg's first pass (MissionRunOptions::rock_variance_pass), after
//                     every leg; nothing to do when the pass does not apply
//   craters           craters: crater detection on the orbital image (no dependency)
//   finish            finish: the legs' test, the bundle adjustment, guided re-registration,
//                     the traverse products, summary.json and report.html (RunMissionFolder,
//                     which reuses every unit above), after everything else
// Every unit runs the same code as the local run, so a plan executed anywhere gives the local
// run's figures and files. Units are claimed (unit_claim.h): many executors on one plan run each
// unit once; a unit whose holder died runs again.
// Failure: a plan whose mission inputs or options no longer give its fingerprint is refused
// (plan again); a unit that fails writes error.txt in its folder and is reported, the other
// named units still run.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "areomap/map/mission_manifest.h"
#include "areomap/map/progress.h"
#include "areomap/pipeline/mission_run.h"
#include "areomap/pipeline/unit_claim.h"
#include "areomap/pipeline/work_plan.h"

namespace areomap {

// The plan of `mission` into `out_dir` with `options`; `arguments` are the run command's options
// as given (recorded for run-unit to read again).
WorkPlan PlanMission(const MissionManifest& mission, const std::filesystem::path& out_dir,
                     const MissionRunOptions& options, std::vector<std::string> arguments);

// `areomap run MISSION --out DIR --plan`: checks `options`, reads the manifest (every file it
// names checked), and writes out_dir/plan.json under the output-folder policy of the run
// (WritePlanInFolder: the plan's files are the run's; the same plan already there is returned as
// it is). Throws areomap::Error as those steps do.
WorkPlan PlanMissionFolder(const std::filesystem::path& mission,
                           const std::filesystem::path& out_dir, const MissionRunOptions& options,
                           const std::vector<std::string>& arguments, bool overwrite = false);

// How one unit of a run-unit call went.
struct UnitRunRecord {
  std::string id;
  UnitOutcome outcome = UnitOutcome::kFailed;
  std::string error;  // When kFailed: the message (also in the unit's error.txt).
  double seconds = 0.0;
};

// `areomap run-unit DIR UNIT...` on a mission plan read from `out_dir`: runs each named unit in
// order (waiting while another process holds one), records it done (DoneFile) and returns what
// happened to each. `options` must be the plan's (re-read from its
// arguments). Throws areomap::Error before any unit when a unit id is not in the plan or the
// plan's fingerprint no longer matches the mission's files and the options.
std::vector<UnitRunRecord> RunMissionPlanUnits(const std::filesystem::path& out_dir,
                                               const WorkPlan& plan,
                                               const MissionRunOptions& options,
                                               const std::vector<std::string>& unit_ids,
                                               const UnitClaimOptions& claims,
                                               const ProgressCallback& progress = nullptr);

}  // namespace areomap
