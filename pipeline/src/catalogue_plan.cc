#include "areomap/pipeline/catalogue_plan.h"

#include <chrono>
#include <sstream>

#include "areomap/crater/crater_catalogue.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "mission_units.h"

namespace areomap {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

std::string Digits(size_t n) {
  char text[24];
  std::snprintf(text, sizeof(text), "%03zu", n);
  return text;
}

std::string Fingerprint(const std::vector<fs::path>& images,
                        const std::vector<std::string>& arguments) {
  json paths = json::array();
  for (const fs::path& image : images) paths.push_back(image.string());
  return json{{"images", paths}, {"inputs", FilesIdentity(images)}, {"options", arguments}}.dump();
}

std::vector<fs::path> PlanImages(const WorkPlan& plan) {
  return {plan.inputs.begin(), plan.inputs.end()};
}

}  // namespace

WorkPlan PlanCraterCatalogue(const std::vector<fs::path>& images_in,
                             std::vector<std::string> arguments) {
  std::vector<fs::path> images;
  for (const fs::path& image : images_in) images.push_back(fs::absolute(image).lexically_normal());
  WorkPlan plan;
  plan.job = "craters";
  for (const fs::path& image : images) plan.inputs.push_back(image.string());
  plan.fingerprint = Fingerprint(images, arguments);
  plan.arguments = std::move(arguments);
  PlannedStage stage_images{"images", {}, {}};
  PlannedUnit merge{"merge", ".", {}, "the merged craters.gpkg, craters.csv, images.csv"};
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string id = "image_" + Digits(i + 1);
    stage_images.units.push_back(
        {id,
         "images/" + CatalogueImageFolderName(static_cast<int>(i + 1), images[i]),
         {},
         "craters on " + images[i].string()});
    merge.after.push_back(id);
  }
  PlannedStage stage_merge{"merge", {"images"}, {merge}};
  stage_merge.tolerates_failures = true;
  plan.stages = {stage_images, stage_merge};
  return plan;
}

OutputFolderOptions CataloguePlanFolderPolicy(std::vector<fs::path> inputs, bool overwrite) {
  OutputFolderOptions policy;
  policy.command = "craters";
  policy.outputs = {"images/",   "craters.csv", "craters.gpkg", "images.csv", "summary.json",
                    "plan.json", "error.txt",   "slurm/",       "parallel/"};
  policy.inputs = std::move(inputs);
  policy.overwrite = overwrite;
  policy.in_place = true;
  return policy;
}

WorkPlan PlanCraterCatalogueFolder(const std::vector<fs::path>& images,
                                   const std::vector<fs::path>& inputs, const fs::path& out_dir,
                                   const std::vector<std::string>& arguments, bool overwrite) {
  return WritePlanInFolder(out_dir, PlanCraterCatalogue(images, arguments),
                           CataloguePlanFolderPolicy(inputs, overwrite));
}

namespace {

// The merge unit: writes the merged files in place and summary.json; throws areomap::Error naming
// the failed images after writing them.
void MergeUnit(const fs::path& dir, const WorkPlan& plan, const CatalogueMergeOptions& options,
               const json& summary_head, const ProgressCallback& progress) {
  std::vector<fs::path> image_dirs;
  for (const PlannedUnit& unit : plan.Stage("images").units)
    image_dirs.push_back(dir / unit.folder);
  std::vector<fs::path> inputs = PlanImages(plan);
  OutputFolder out(dir, CataloguePlanFolderPolicy(inputs, /*overwrite=*/false));
  const CatalogueMergeSummary s = MergeCraterCatalogues(image_dirs, out.dir(), options, progress);
  json summary = summary_head;
  summary.update(CatalogueMergeSummaryJson(s));
  WriteFileAtomically(out.dir() / "summary.json", summary.dump(2) + "\n");
  out.Commit();
  if (s.images_failed > 0) {
    std::ostringstream failed;
    for (const CatalogueImageRow& row : s.images) {
      if (!row.ok)
        failed << (failed.tellp() > 0 ? "; " : "") << row.image << " (" << row.error << ")";
    }
    throw Error(std::to_string(s.images_failed) + " of " + std::to_string(s.images.size()) +
                " images failed: " + failed.str() + "; the others are merged (images.csv)");
  }
}

}  // namespace

std::vector<UnitRunRecord> RunCataloguePlanUnits(const fs::path& out_dir, const WorkPlan& plan,
                                                 const CraterImageOptions& image,
                                                 const CatalogueMergeOptions& merge,
                                                 const json& summary_head,
                                                 const std::vector<std::string>& unit_ids,
                                                 const UnitClaimOptions& claims,
                                                 const ProgressCallback& progress) {
  if (plan.job != "craters") {
    throw Error((out_dir / kPlanFileName).string() + ": not a plan of `areomap craters` (job \"" +
                plan.job + "\")");
  }
  claims.Check();
  for (const std::string& id : unit_ids) plan.Unit(id);  // Unknown ids fail before any work.
  const fs::path dir = fs::absolute(out_dir).lexically_normal();
  if (Fingerprint(PlanImages(plan), plan.arguments) != plan.fingerprint) {
    throw Error((dir / kPlanFileName).string() +
                ": an image changed since this plan was written; write the plan again (areomap "
                "craters IMAGE... --out " +
                dir.string() + " --plan)");
  }
  CraterImageOptions image_options = image;
  image_options.require_ground = true;
  image_options.Check();
  bool model_checked = false;  // Loaded once, for the first image unit (not for the merge).
  std::vector<UnitRunRecord> records;
  for (const std::string& id : unit_ids) {
    const PlannedStage* stage = nullptr;
    const PlannedUnit& unit = plan.Unit(id, &stage);
    UnitRunRecord record;
    record.id = id;
    const auto start = std::chrono::steady_clock::now();
    const auto work = [&] {
      if (stage->name == "merge") {
        MergeUnit(dir, plan, merge, summary_head, progress);
        return;
      }
      if (!model_checked) CheckCraterModel(image_options);
      model_checked = true;
      const size_t index = static_cast<size_t>(&unit - stage->units.data());
      const CatalogueImageRecord r =
          RunCraterCatalogueImage(plan.inputs[index], dir / unit.folder, image_options, progress);
      if (!r.ok) throw Error(r.error);
    };
    const UnitOutcome outcome = RunClaimedUnit(
        ClaimFile(dir, id), ErrorFile(dir, unit), id,
        [&] { return DoneFileMatches(dir, id, plan.fingerprint); },
        [&] {
          work();
          WriteDoneFile(dir, id, plan.fingerprint);
        },
        claims, /*wait=*/true, &record.error);
    record.outcome = outcome;
    record.seconds = mission_run::SecondsSince(start);
    records.push_back(record);
  }
  return records;
}

}  // namespace areomap
