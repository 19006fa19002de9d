// Executors of a plan (work_plan.h, docs/cluster.md): existing engines run its units, areomap
// schedules nothing itself. Each unit is one `areomap run-unit DIR --stage NAME --task-index I`
// process; units claim themselves (unit_claim.h), so executors may overlap.
//  - Slurm: one job array per stage (task i = the stage's unit i), each submitted with
//    --dependency=afterok on the arrays of the stages it waits for (afterany for a stage that
//    tolerates failures) and --kill-on-invalid-dep=yes (a failed unit cancels what depends on
//    it rather than leaving it pending). The batch scripts
//    are written to DIR/slurm/ (STAGE.sbatch) and each task's output to
//    DIR/slurm/STAGE-JOB_TASK.out.
//  - GNU parallel: stage by stage, the stage's units through `parallel` on local job slots or
//    over ssh hosts (--sshloginfile, ASP's parallel_stereo model), DIR/parallel/STAGE.units
//    the list it reads; a stage whose units failed stops the stages that wait for it (unless
//    they tolerate failures).
// The areomap executable must be reachable at the same path on every host (a shared install).
// Failure: a missing engine (sbatch, parallel), a refused submission or a failed unit throws
// areomap::Error naming the command or the units and their error.txt.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "areomap/pipeline/unit_claim.h"
#include "areomap/pipeline/work_plan.h"

namespace areomap {

// The state of one planned unit, as DIR says now.
enum class UnitState { kDone, kRunning, kFailed, kPending };
const char* ToString(UnitState state);

struct UnitStatus {
  std::string stage;
  std::string id;
  UnitState state = UnitState::kPending;
  // kRunning: the holder (host:pid, last touched); kFailed: the error's first line; kPending
  // with a stale claim: that claim's holder.
  std::string detail;
};

// Done: its DoneFile matches the plan's fingerprint; running: a live claim; failed: error.txt in
// its folder; else pending.
std::vector<UnitStatus> ReadPlanStatus(const std::filesystem::path& dir, const WorkPlan& plan,
                                       const UnitClaimOptions& claims = {});

// What every executor passes to run-unit and how it finds areomap.
struct ExecutorOptions {
  std::string executable;  // The areomap binary; empty: this process's (/proc/self/exe).
  std::vector<std::string> run_unit_arguments;  // Extra run-unit options (--stale-after S).
};

struct SlurmOptions {
  ExecutorOptions executor;
  std::vector<std::string> sbatch_arguments;  // Added to every sbatch call (--partition=x ...).
};

// The job ids of a submission, per stage, in plan order.
struct SlurmSubmission {
  std::vector<std::pair<std::string, std::string>> jobs;  // (stage, job id)
};

// Submits every stage with units as a job array (see above) and returns at once.
SlurmSubmission SubmitPlanToSlurm(const std::filesystem::path& dir, const WorkPlan& plan,
                                  const SlurmOptions& options);
// Returns when no job of `submission` is queued or running any more (squeue asked every
// `poll_s`); throws areomap::Error listing the plan's units that are not done then (with their
// error.txt's message).
void WaitForSlurmJobs(const std::filesystem::path& dir, const WorkPlan& plan,
                      const SlurmSubmission& submission, double poll_s = 5.0);

struct ParallelOptions {
  ExecutorOptions executor;
  int jobs = 0;                      // Job slots per host; 0: parallel's default (cores).
  std::filesystem::path hosts_file;  // --sshloginfile; empty: this machine only.
  std::vector<std::string> parallel_arguments;  // Added to every parallel call (--ssh CMD ...).
};

// Runs the plan's stages in order through GNU parallel; `stage_done` (optional) hears each stage
// that ended with every unit done. Throws areomap::Error listing the units not done at the end.
void RunPlanWithGnuParallel(const std::filesystem::path& dir, const WorkPlan& plan,
                            const ParallelOptions& options,
                            const std::function<void(const std::string&)>& stage_done = nullptr);

// Splits an option string the way a shell would split plain words: at blanks, with '...' and
// "..." keeping blanks inside a word. Throws areomap::Error on an unclosed quote.
std::vector<std::string> SplitArguments(const std::string& text);

}  // namespace areomap
