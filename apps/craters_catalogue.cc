// areomap craters IMAGE... [--list FILE] --out DIR: one crater catalogue over many images
// (crater_catalogue.h per image, crater_catalogue_merge.h for the merged files).
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "areomap/crater/crater_catalogue.h"
#include "areomap/crater/crater_catalogue_merge.h"
#include "areomap/map/error.h"
#include "areomap/pipeline/catalogue_plan.h"
#include "craters_args.h"

namespace areomap::cli {
namespace {

namespace fs = std::filesystem;

// The command line's rasters, then the list's; a missing one is refused before any work.
std::vector<fs::path> CatalogueImages(const CratersArgs& a) {
  std::vector<fs::path> images;
  for (size_t i = 0; i < a.inputs.size(); ++i) {
    std::error_code ec;
    if (!fs::exists(a.inputs[i], ec)) {
      throw Error("craters: " + a.inputs[i] + ": no such file (image " + std::to_string(i + 1) +
                  " on the command line)");
    }
    images.emplace_back(a.inputs[i]);
  }
  if (!a.list.empty()) {
    const std::vector<fs::path> listed = ReadCatalogueImageList(a.list);
    if (listed.empty()) throw Error("craters: " + a.list + ": the list names no image");
    images.insert(images.end(), listed.begin(), listed.end());
  }
  return images;
}

// The images, the files the command reads (the images and the list) and the options, checked
// (the model loaded) before any output.
struct CatalogueInputs {
  std::vector<fs::path> images;
  std::vector<fs::path> inputs;
  CraterImageOptions options;
};

CatalogueInputs PrepareCatalogue(const CratersArgs& a) {
  CatalogueInputs c;
  c.images = CatalogueImages(a);
  c.options = ImageOptions(a);
  c.options.require_ground = true;
  CheckCraterModel(c.options);
  c.inputs = c.images;
  if (!a.list.empty()) c.inputs.emplace_back(a.list);
  return c;
}

std::string FailedImages(const CatalogueMergeSummary& s) {
  std::ostringstream text;
  for (const CatalogueImageRow& row : s.images) {
    if (row.ok) continue;
    text << (text.tellp() > 0 ? "; " : "") << row.image << " (" << row.error << ")";
  }
  return text.str();
}

}  // namespace

nlohmann::json CatalogueSummaryHead(const CratersArgs& a) {
  return {{"command", "craters"},
          {"mode", "catalogue"},
          {"list", a.list.empty() ? nlohmann::json() : nlohmann::json(a.list)},
          {"method", a.image.dtm ? "edges" : a.method},
          {"source", a.image.dtm ? "dtm" : "image"},
          {"files", {"craters.gpkg", "craters.csv", "images.csv", "images/"}}};
}

void RunPlannedCraterCatalogue(const CratersArgs& a, const std::vector<std::string>& arguments,
                               const GlobalOptions& global) {
  const CatalogueInputs c = PrepareCatalogue(a);
  const std::vector<fs::path>& images = c.images;
  const std::vector<fs::path>& inputs = c.inputs;
  const WorkPlan plan =
      PlanCraterCatalogueFolder(images, inputs, a.out_dir, arguments, global.overwrite);
  if (RunPlan(a.out_dir, plan, a.executor, global) && !global.quiet) {
    const nlohmann::json s = ReadJsonFile(fs::path(a.out_dir) / "summary.json");
    std::cout << "catalogue of " << s.value("images", 0) << " images ("
              << s.value("images_failed", 0) << " failed): " << s.value("craters_detected", 0)
              << " craters detected, " << s.value("craters_kept", 0) << " kept, "
              << s.value("duplicates_removed", 0) << " duplicates removed; wrote " << a.out_dir
              << "\n";
  }
}

void RunCraterCatalogue(const CratersArgs& a, const GlobalOptions& global) {
  const CatalogueInputs c = PrepareCatalogue(a);
  const std::vector<fs::path>& images = c.images;
  const CraterImageOptions& options = c.options;
  OutputFolder folder(
      a.out_dir, OutputPolicy(global, "craters",
                              {"images/", "craters.csv", "craters.gpkg", "images.csv"}, c.inputs));
  std::vector<fs::path> dirs;
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string name = CatalogueImageFolderName(static_cast<int>(i + 1), images[i]);
    dirs.push_back(folder.dir() / "images" / name);
    const CatalogueImageRecord r =
        RunCraterCatalogueImage(images[i], dirs.back(), options, MakeProgressBar(global, name));
    for (const std::string& w : r.warnings) std::cerr << "warning: " << w << "\n";
    if (global.quiet) continue;
    std::cout << "[" << i + 1 << "/" << images.size() << "] " << name << ": ";
    if (r.ok) {
      std::cout << r.craters << " craters, " << std::fixed << std::setprecision(1) << r.seconds
                << " s\n";
    } else {
      std::cout << "failed: " << r.error << "\n";
    }
  }
  CatalogueMergeOptions merge;
  merge.crs = a.crs;
  const CatalogueMergeSummary s =
      MergeCraterCatalogues(dirs, folder.dir(), merge, MakeProgressBar(global, "merge"));
  nlohmann::json summary = CatalogueSummaryHead(a);
  summary.update(CatalogueMergeSummaryJson(s));
  WriteSummary(folder.dir(), summary);
  folder.Commit();
  if (!global.quiet) {
    std::cout << "catalogue of " << s.images.size() << " images (" << s.images_failed
              << " failed): " << s.detected << " craters detected, " << s.kept << " kept, "
              << s.duplicates_removed << " duplicates removed; wrote " << a.out_dir << "\n";
  }
  if (s.images_failed > 0) {
    throw Error("craters: " + std::to_string(s.images_failed) + " of " +
                std::to_string(s.images.size()) + " images failed: " + FailedImages(s) +
                "; the others are merged in " + a.out_dir + " (images.csv)");
  }
}

}  // namespace areomap::cli
