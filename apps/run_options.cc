#include "run_options.h"

#include <cstdio>
#include <fstream>

#include "areomap/map/error.h"
#include "areomap/pipeline/executors.h"

namespace areomap::cli {

namespace fs = std::filesystem;

std::vector<std::string> ArgumentsGiven(const CLI::App& group) {
  std::vector<std::string> words;
  for (const CLI::Option* option : group.get_options()) {
    if (option->count() == 0 || option->get_positional()) continue;
    const std::string name = option->get_name();
    if (option->get_expected_max() == 0) {  // A flag.
      for (size_t i = 0; i < option->count(); ++i) words.push_back(name);
      continue;
    }
    for (const std::string& value : option->results()) {
      words.push_back(name);
      words.push_back(value);
    }
  }
  return words;
}

void AddExecutorOptions(CLI::App* command, ExecutorArguments* o) {
  auto* group = command->add_option_group(
      "Cluster options", "Plan the job and run it on many processes or hosts (docs/cluster.md)");
  group->add_flag("--plan", o->plan_only,
                  "Only write DIR/plan.json: the units and their order, for `areomap run-unit`");
  group
      ->add_option("--executor", o->executor,
                   "Who runs the units: this process (local), Slurm job arrays (slurm) or GNU "
                   "parallel on local cores or --hosts (parallel)")
      ->check(CLI::IsMember({"local", "slurm", "parallel"}))
      ->capture_default_str();
  group->add_option(
      "--slurm-args", o->slurm_args,
      "Options added to every sbatch call, e.g. \"--partition=short --time=1:00:00\"");
  group->add_flag("--wait", o->wait, "With slurm: return when the jobs have finished");
  group->add_option("--hosts", o->hosts,
                    "With parallel: GNU parallel's --sshloginfile (one ssh login per line, ':' "
                    "for this machine)");
  group->add_option("--jobs", o->jobs, "With parallel: job slots per host (0: its cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  group->add_option("--parallel-args", o->parallel_args,
                    "Options added to every parallel call, e.g. \"--ssh 'ssh -p 2222'\"");
  group
      ->add_option("--stale-after", o->stale_after_s,
                   "A unit's claim untouched this long is taken over (its holder died) [s]")
      ->check(CLI::Range(20.0, 86400.0))
      ->capture_default_str();
}

bool RunPlan(const fs::path& dir, const WorkPlan& plan, const ExecutorArguments& arguments,
             const GlobalOptions& global) {
  ExecutorOptions executor;
  char stale[32];
  std::snprintf(stale, sizeof(stale), "%g", arguments.stale_after_s);
  executor.run_unit_arguments = {"--stale-after", stale};
  if (global.quiet) executor.run_unit_arguments.push_back("--quiet");
  if (arguments.plan_only || arguments.executor == "local") {
    if (!global.quiet) {
      std::printf(
          "plan: %s (%zu units in %zu stages); run them with `areomap run-unit %s UNIT...`\n",
          (dir / kPlanFileName).c_str(), plan.UnitCount(), plan.stages.size(), dir.c_str());
    }
    return false;
  }
  if (arguments.executor == "slurm") {
    SlurmOptions slurm;
    slurm.executor = executor;
    slurm.sbatch_arguments = SplitArguments(arguments.slurm_args);
    const SlurmSubmission submission = SubmitPlanToSlurm(dir, plan, slurm);
    if (!global.quiet) {
      for (const auto& [stage, id] : submission.jobs) {
        std::printf("slurm job %s: stage %s (%zu tasks)\n", id.c_str(), stage.c_str(),
                    plan.Stage(stage).units.size());
      }
      std::printf("%s `areomap run-status %s`\n",
                  arguments.wait ? "waiting for the jobs; follow with" : "follow with",
                  dir.c_str());
      std::fflush(stdout);
    }
    if (arguments.wait) WaitForSlurmJobs(dir, plan, submission);
    return arguments.wait;
  }
  ParallelOptions parallel;
  parallel.executor = executor;
  parallel.jobs = arguments.jobs;
  parallel.hosts_file = arguments.hosts;
  parallel.parallel_arguments = SplitArguments(arguments.parallel_args);
  RunPlanWithGnuParallel(dir, plan, parallel, [&](const std::string& stage) {
    if (!global.quiet) {
      std::printf("stage %s: %zu units done\n", stage.c_str(), plan.Stage(stage).units.size());
      std::fflush(stdout);
    }
  });
  return true;
}

nlohmann::json ReadJsonFile(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot be read");
  const nlohmann::json parsed = nlohmann::json::parse(in, nullptr, false);
  if (parsed.is_discarded()) throw Error(path.string() + ": not valid JSON");
  return parsed;
}

}  // namespace areomap::cli
