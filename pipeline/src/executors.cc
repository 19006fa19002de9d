#include "areomap/pipeline/executors.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

extern char** environ;

namespace areomap {

namespace fs = std::filesystem;

const char* ToString(UnitState state) {
  switch (state) {
    case UnitState::kDone:
      return "done";
    case UnitState::kRunning:
      return "running";
    case UnitState::kFailed:
      return "failed";
    case UnitState::kPending:
      return "pending";
  }
  return "?";
}

std::vector<UnitStatus> ReadPlanStatus(const fs::path& dir, const WorkPlan& plan,
                                       const UnitClaimOptions& claims) {
  std::vector<UnitStatus> status;
  for (const PlannedStage& stage : plan.stages) {
    for (const PlannedUnit& unit : stage.units) {
      UnitStatus s{stage.name, unit.id, UnitState::kPending, ""};
      const std::optional<ClaimHolder> holder = ReadClaimHolder(ClaimFile(dir, unit.id));
      if (DoneFileMatches(dir, unit.id, plan.fingerprint)) {
        s.state = UnitState::kDone;
      } else if (holder && !IsStale(*holder, claims)) {
        s.state = UnitState::kRunning;
        s.detail = holder->ToString();
      } else if (std::ifstream error(ErrorFile(dir, unit)); error) {
        s.state = UnitState::kFailed;
        for (std::string line; std::getline(error, line);) {
          if (line.rfind("error: ", 0) == 0) s.detail = line.substr(7);
        }
      } else if (holder) {
        s.detail = "stale claim by " + holder->ToString();
      }
      status.push_back(std::move(s));
    }
  }
  return status;
}

std::vector<std::string> SplitArguments(const std::string& text) {
  std::vector<std::string> words;
  std::string word;
  bool in_word = false;
  char quote = 0;
  for (const char c : text) {
    if (quote) {
      if (c == quote) {
        quote = 0;
      } else {
        word += c;
      }
    } else if (c == '\'' || c == '"') {
      quote = c;
      in_word = true;
    } else if (c == ' ' || c == '\t' || c == '\n') {
      if (in_word) words.push_back(word);
      word.clear();
      in_word = false;
    } else {
      word += c;
      in_word = true;
    }
  }
  if (quote) throw Error("unclosed " + std::string(1, quote) + " in the options \"" + text + "\"");
  if (in_word) words.push_back(word);
  return words;
}

namespace {

struct ProgramResult {
  int exit_code = -1;
  std::string output;  // Its standard output when captured.
};

// Runs `argv` (found on PATH) and waits; captures its standard output when `capture`, standard
// error goes to ours. Throws areomap::Error when it cannot be started.
ProgramResult RunProgram(const std::vector<std::string>& argv, bool capture) {
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  int pipe_fds[2] = {-1, -1};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (capture) {
    if (::pipe(pipe_fds) != 0)
      throw Error("cannot make a pipe: " + std::string(std::strerror(errno)));
    posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, pipe_fds[0]);
  }
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (capture) ::close(pipe_fds[1]);
  if (spawned != 0) {
    if (capture) ::close(pipe_fds[0]);
    throw Error("cannot run `" + argv[0] + "`: " + std::strerror(spawned) +
                " (is it installed and on PATH?)");
  }
  ProgramResult result;
  if (capture) {
    char buffer[4096];
    ssize_t n = 0;
    while ((n = ::read(pipe_fds[0], buffer, sizeof(buffer))) > 0 || (n < 0 && errno == EINTR)) {
      if (n > 0) result.output.append(buffer, static_cast<size_t>(n));
    }
    ::close(pipe_fds[0]);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

std::string Executable(const ExecutorOptions& options) {
  if (!options.executable.empty()) return options.executable;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error("cannot tell where the areomap executable is (/proc/self/exe)");
  return self.string();
}

// 'text' for a POSIX shell.
std::string ShellQuote(const std::string& text) {
  std::string quoted = "'";
  for (const char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

std::string Join(const std::vector<std::string>& words, const char* separator) {
  std::string text;
  for (const std::string& w : words) text += (text.empty() ? "" : separator) + w;
  return text;
}

// The units that are not done, with why, as lines; empty when every unit of `stages` is done.
std::string NotDone(const fs::path& dir, const WorkPlan& plan,
                    const std::vector<std::string>& stages) {
  std::string lines;
  for (const UnitStatus& s : ReadPlanStatus(dir, plan)) {
    if (s.state == UnitState::kDone) continue;
    if (!stages.empty() && std::find(stages.begin(), stages.end(), s.stage) == stages.end()) {
      continue;
    }
    lines += "\n  " + s.id + ": " + ToString(s.state) + (s.detail.empty() ? "" : ", " + s.detail);
  }
  return lines;
}

// How the units of one stage stand after its executor ran.
struct StageOutcome {
  bool all_done = true;
  bool none_started = true;  // None done, running or failed.
};

StageOutcome OutcomeOf(const std::vector<UnitStatus>& status, const std::string& stage) {
  StageOutcome outcome;
  for (const UnitStatus& s : status) {
    if (s.stage != stage) continue;
    outcome.all_done = outcome.all_done && s.state == UnitState::kDone;
    outcome.none_started = outcome.none_started && s.state == UnitState::kPending;
  }
  return outcome;
}

}  // namespace

SlurmSubmission SubmitPlanToSlurm(const fs::path& dir_in, const WorkPlan& plan,
                                  const SlurmOptions& options) {
  const fs::path dir = fs::absolute(dir_in).lexically_normal();
  const std::string executable = Executable(options.executor);
  fs::create_directories(dir / "slurm");
  SlurmSubmission submission;
  std::map<std::string, std::string> job_of_stage;
  for (const PlannedStage& stage : plan.stages) {
    if (stage.units.empty()) continue;
    const fs::path script = dir / "slurm" / (stage.name + ".sbatch");
    std::string command = "exec " + ShellQuote(executable) + " run-unit " +
                          ShellQuote(dir.string()) + " --stage " + ShellQuote(stage.name) +
                          " --task-index \"$SLURM_ARRAY_TASK_ID\"";
    for (const std::string& a : options.executor.run_unit_arguments) {
      command += ' ';
      command += ShellQuote(a);
    }
    WriteFileAtomically(script, "#!/bin/sh\n# areomap: stage \"" + stage.name + "\" of " +
                                    (dir / kPlanFileName).string() +
                                    ", one array task per unit (docs/cluster.md).\n" + command +
                                    "\n");
    std::vector<std::string> argv = {
        "sbatch",
        "--parsable",
        "--job-name=areomap-" + stage.name,
        "--output=" + (dir / "slurm" / (stage.name + "-%A_%a.out")).string(),
        "--array=0-" + std::to_string(stage.units.size() - 1),
        "--kill-on-invalid-dep=yes"};
    std::vector<std::string> after;
    for (const std::string& name : stage.after) {
      if (job_of_stage.count(name)) after.push_back(job_of_stage[name]);
    }
    if (!after.empty()) {
      argv.push_back(std::string("--dependency=") +
                     (stage.tolerates_failures ? "afterany:" : "afterok:") + Join(after, ":"));
    }
    argv.insert(argv.end(), options.sbatch_arguments.begin(), options.sbatch_arguments.end());
    argv.push_back(script.string());
    const ProgramResult result = RunProgram(argv, /*capture=*/true);
    const std::string id = result.output.substr(0, result.output.find_first_of(";\n"));
    if (result.exit_code != 0 || id.empty() ||
        id.find_first_not_of("0123456789") != std::string::npos) {
      throw Error("sbatch refused the stage \"" + stage.name + "\" (exit " +
                  std::to_string(result.exit_code) + ", output \"" + result.output +
                  "\"): " + Join(argv, " "));
    }
    job_of_stage[stage.name] = id;
    submission.jobs.emplace_back(stage.name, id);
  }
  return submission;
}

void WaitForSlurmJobs(const fs::path& dir_in, const WorkPlan& plan,
                      const SlurmSubmission& submission, double poll_s) {
  const fs::path dir = fs::absolute(dir_in).lexically_normal();
  std::vector<std::string> ids;
  for (const auto& [stage, id] : submission.jobs) ids.push_back(id);
  while (true) {
    const ProgramResult queued =
        RunProgram({"squeue", "--noheader", "--format=%i", "--jobs=" + Join(ids, ",")}, true);
    if (queued.exit_code != 0 || queued.output.find_first_not_of(" \n") == std::string::npos) {
      break;  // squeue refuses ids that have all left the queue.
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(poll_s));
  }
  const std::string missing = NotDone(dir, plan, {});
  if (!missing.empty()) {
    throw Error("the Slurm jobs ended with units not done (their error.txt, DIR/slurm/*.out):" +
                missing);
  }
}

void RunPlanWithGnuParallel(const fs::path& dir_in, const WorkPlan& plan,
                            const ParallelOptions& options,
                            const std::function<void(const std::string&)>& stage_done) {
  const fs::path dir = fs::absolute(dir_in).lexically_normal();
  const std::string executable = Executable(options.executor);
  fs::create_directories(dir / "parallel");
  std::vector<std::string> failed_stages;  // Stages that ended with units not done.
  std::string none_started;                // Stages that parallel ran without starting a unit.
  for (const PlannedStage& stage : plan.stages) {
    if (stage.units.empty()) continue;
    const bool blocked = std::any_of(stage.after.begin(), stage.after.end(), [&](const auto& s) {
      return std::find(failed_stages.begin(), failed_stages.end(), s) != failed_stages.end();
    });
    if (blocked && !stage.tolerates_failures) {
      failed_stages.push_back(stage.name);  // Not run: what it needs failed.
      continue;
    }
    const fs::path list = dir / "parallel" / (stage.name + ".units");
    std::string ids;
    for (const PlannedUnit& unit : stage.units) ids += unit.id + "\n";
    WriteFileAtomically(list, ids);
    std::vector<std::string> argv = {"parallel", "--will-cite", "--halt", "never", "--quote"};
    if (options.jobs > 0) argv.insert(argv.end(), {"--jobs", std::to_string(options.jobs)});
    if (!options.hosts_file.empty()) {
      argv.insert(argv.end(), {"--sshloginfile", fs::absolute(options.hosts_file).string()});
    }
    argv.insert(argv.end(), options.parallel_arguments.begin(), options.parallel_arguments.end());
    argv.insert(argv.end(),
                {"--arg-file", list.string(), executable, "run-unit", dir.string(), "{}"});
    argv.insert(argv.end(), options.executor.run_unit_arguments.begin(),
                options.executor.run_unit_arguments.end());
    RunProgram(argv, /*capture=*/false);
    const StageOutcome outcome = OutcomeOf(ReadPlanStatus(dir, plan), stage.name);
    if (!outcome.all_done) {
      failed_stages.push_back(stage.name);
      if (outcome.none_started) none_started.append(" ").append(stage.name);
    } else if (stage_done) {
      stage_done(stage.name);
    }
  }
  const std::string missing = NotDone(dir, plan, {});
  if (!missing.empty()) {
    throw Error(
        "GNU parallel ended with units not done (their error.txt; stages after a failed "
        "one are not run):" +
        missing +
        (none_started.empty()
             ? std::string()
             : "\nGNU parallel started no unit of stage(s)" + none_started + ": each host needs " +
                   executable + ", the folder " + dir.string() +
                   " and, for its remote worker, SHELL set in the environment"));
  }
}

}  // namespace areomap
