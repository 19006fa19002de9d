#include "areomap/pipeline/mission_plan.h"

#include <chrono>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/output_folder.h"
#include "mission_units.h"

namespace areomap {

namespace fs = std::filesystem;
using nlohmann::json;
using namespace mission_run;

namespace {

std::string Relative(const fs::path& path, const fs::path& root) {
  return path.lexically_relative(root).generic_string();
}

}  // namespace

WorkPlan PlanMission(const MissionManifest& mission, const fs::path& out_dir,
                     const MissionRunOptions& options, std::vector<std::string> arguments) {
  options.Check();
  const fs::path dir = fs::absolute(out_dir).lexically_normal();
  const RunContext run(mission, options, dir);
  WorkPlan plan;
  plan.job = "run";
  plan.inputs = {fs::absolute(mission.root).lexically_normal().string()};
  plan.arguments = std::move(arguments);
  plan.fingerprint = run.fingerprint;

  PlannedStage sites{"sites", {}, {}};
  for (const MissionSite& site : mission.sites) {
    sites.units.push_back(
        {SiteUnitId(site.site),
         Relative(SiteDir(run, site.site), dir),
         {},
         "stereo, DTM, orthophoto and orbital registration of site " + std::to_string(site.site)});
  }
  PlannedStage legs{"legs", {"sites"}, {}};
  PlannedStage second{"legs_second_pass", {"legs"}, {}};
  std::vector<std::string> leg_ids;
  for (size_t i = 0; i + 1 < mission.sites.size(); ++i) {
    const int a = mission.sites[i].site, b = mission.sites[i + 1].site;
    leg_ids.push_back(LegUnitId(a, b));
    legs.units.push_back({LegUnitId(a, b),
                          Relative(LegDir(run, a, b), dir),
                          {SiteUnitId(a), SiteUnitId(b)},
                          "rocks and cross-site matching of sites " + std::to_string(a) + " and " +
                              std::to_string(b) + " (first pass)"});
  }
  for (size_t i = 0; i + 1 < mission.sites.size(); ++i) {
    const int a = mission.sites[i].site, b = mission.sites[i + 1].site;
    second.units.push_back({SecondPassUnitId(a, b), Relative(LegDir(run, a, b), dir), leg_ids,
                            "the leg matched again with the rock ties' pooled variance factor "
                            "when the second pass applies"});
  }
  PlannedStage craters{"craters", {}, {}};
  if (options.detect_craters) {
    craters.units.push_back({"craters", "craters", {}, "crater detection on the orbital image"});
  }
  PlannedStage finish{"finish", {"sites", "legs_second_pass"}, {}};
  PlannedUnit last{"finish", ".", {}, ""};
  for (const PlannedStage* stage : {&sites, &second, &craters}) {
    for (const PlannedUnit& unit : stage->units) last.after.push_back(unit.id);
  }
  if (!craters.units.empty()) finish.after.push_back("craters");
  last.description =
      "the legs' test, bundle adjustment, guided re-registration, traverse products, "
      "summary.json and report.html";
  finish.units.push_back(last);
  plan.stages = {sites, legs, second};
  if (!craters.units.empty()) plan.stages.push_back(craters);
  plan.stages.push_back(finish);
  return plan;
}

WorkPlan PlanMissionFolder(const fs::path& mission, const fs::path& out_dir,
                           const MissionRunOptions& options,
                           const std::vector<std::string>& arguments, bool overwrite) {
  options.Check();
  const MissionManifest manifest = ReadMissionManifest(mission);  // Every file it names checked.
  return WritePlanInFolder(out_dir, PlanMission(manifest, out_dir, options, arguments),
                           RunFolderPolicy(mission, overwrite));
}

namespace {

// The variance factor of the legs' second pass, for that stage's units: pooled once from every
// leg's first pass and kept in DIR/.areomap-units/second_pass.json with the plan's fingerprint,
// so that each of the stage's units (one per leg, each maybe its own process) reads that file
// rather than every leg's record. Throws areomap::Error naming the first leg not finished.
std::optional<double> PlannedSecondPassFactor(const RunContext& run) {
  const fs::path record = run.out_dir / kUnitsFolderName / "second_pass.json";
  const json kept = ReadJsonOrNull(record);
  if (kept.is_object() && kept.value("fingerprint", "") == run.fingerprint) {
    const json factor = kept.value("factor", json());
    return factor.is_number() ? std::optional<double>(factor.get<double>()) : std::nullopt;
  }
  std::vector<LegUnitResult> legs;
  const std::vector<MissionSite>& sites = run.mission->sites;
  for (size_t i = 0; i + 1 < sites.size(); ++i) {
    std::optional<LegUnitResult> leg =
        FinishedUnitResult<LegUnitResult>(run, LegDir(run, sites[i].site, sites[i + 1].site));
    if (!leg) {
      throw Error("the legs' second pass needs every leg's first pass; " +
                  LegUnitId(sites[i].site, sites[i + 1].site) + " is not finished");
    }
    legs.push_back(std::move(*leg));
  }
  const std::optional<double> factor = SecondPassFactor(run, legs);
  fs::create_directories(record.parent_path());
  WriteFileAtomically(
      record,
      json{{"fingerprint", run.fingerprint}, {"factor", factor ? json(*factor) : json()}}.dump());
  return factor;
}

// Runs one planned unit of the run (the `index`-th of its stage: PlanMission lists sites and
// legs in the mission's order), under its claim; true when it was already done. Throws
// areomap::Error on failure.
bool RunOneMissionUnit(const RunContext& run, const fs::path& mission_folder,
                       const PlannedStage& stage, size_t index, SiteRocksCache& rocks,
                       const ProgressCallback& progress) {
  bool reused = false;
  if (stage.name == "sites") {
    EnsureSiteUnit(run, index, progress, &reused);
  } else if (stage.name == "legs") {
    EnsureLegUnit(run, index, rocks, progress, &reused);
  } else if (stage.name == "legs_second_pass") {
    const std::optional<double> factor = PlannedSecondPassFactor(run);
    const MissionSite& a = run.mission->sites[index];
    const MissionSite& b = run.mission->sites[index + 1];
    std::optional<LegUnitResult> leg =
        FinishedUnitResult<LegUnitResult>(run, LegDir(run, a.site, b.site));
    if (!leg) {
      throw Error(SecondPassUnitId(a.site, b.site) + " needs the leg unit " +
                  LegUnitId(a.site, b.site) + " finished first");
    }
    reused = !EnsureLegSecondPass(run, index, rocks, factor, *leg, progress);
  } else if (stage.name == "craters") {
    EnsureCratersUnit(run, progress, &reused);
  } else if (stage.name == "finish") {
    const std::string id = stage.units[index].id;
    std::string error;
    const UnitOutcome outcome = RunClaimedUnit(
        ClaimFile(run.out_dir, id), run.out_dir / "error.txt", id,
        [&] { return DoneFileMatches(run.out_dir, id, run.fingerprint); },
        [&] {
          RunMissionFolder(mission_folder, run.out_dir, *run.options, /*overwrite=*/false,
                           progress);
          WriteDoneFile(run.out_dir, id, run.fingerprint);
        },
        run.claims, /*wait=*/true, &error);
    if (outcome == UnitOutcome::kFailed) throw Error(error);
    reused = outcome == UnitOutcome::kReused;
  } else {
    throw Error("not a stage of a mission plan: " + stage.name);
  }
  return reused;
}

}  // namespace

std::vector<UnitRunRecord> RunMissionPlanUnits(const fs::path& out_dir, const WorkPlan& plan,
                                               const MissionRunOptions& options,
                                               const std::vector<std::string>& unit_ids,
                                               const UnitClaimOptions& claims,
                                               const ProgressCallback& progress) {
  if (plan.job != "run" || plan.inputs.size() != 1) {
    throw Error((out_dir / kPlanFileName).string() + ": not a plan of `areomap run` (job \"" +
                plan.job + "\")");
  }
  options.Check();
  claims.Check();
  for (const std::string& id : unit_ids) plan.Unit(id);  // Unknown ids fail before any work.
  const fs::path dir = fs::absolute(out_dir).lexically_normal();
  const MissionManifest mission = ReadMissionManifest(plan.inputs[0]);
  RunContext run(mission, options, dir);
  run.claims = claims;
  if (run.fingerprint != plan.fingerprint) {
    throw Error((dir / kPlanFileName).string() +
                ": the mission's files or the options changed since this plan was written; write "
                "the plan again (areomap run " +
                plan.inputs[0] + " --out " + dir.string() + " --plan)");
  }
  SiteRocksCache rocks(run);
  std::vector<UnitRunRecord> records;
  for (const std::string& id : unit_ids) {
    UnitRunRecord record;
    record.id = id;
    const auto start = std::chrono::steady_clock::now();
    try {
      const PlannedStage* stage = nullptr;
      const PlannedUnit& unit = plan.Unit(id, &stage);
      const size_t index = static_cast<size_t>(&unit - stage->units.data());
      const bool reused = RunOneMissionUnit(run, plan.inputs[0], *stage, index, rocks, progress);
      record.outcome = reused ? UnitOutcome::kReused : UnitOutcome::kComputed;
      WriteDoneFile(dir, id, plan.fingerprint);
    } catch (const std::exception& e) {
      record.outcome = UnitOutcome::kFailed;
      record.error = e.what();
      WriteUnitError(ErrorFile(dir, plan.Unit(id)), id, e.what());
    }
    record.seconds = SecondsSince(start);
    records.push_back(record);
  }
  return records;
}

}  // namespace areomap
