// The options of `areomap craters` shared by its two modes: one raster (craters_command.cc) and
// a catalogue over many images (craters_catalogue.cc).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/crater/crater_image.h"
#include "cli_common.h"
#include "run_options.h"

namespace areomap::cli {

struct CratersArgs {
  std::vector<std::string> inputs;  // rasters on the command line
  std::string list;                 // --list FILE: more images, one a line
  std::string out_dir;
  std::string units = "px";
  std::string method = "combined";
  std::string crs;  // catalogue: the merged catalogue's CRS (empty: the first image's)
  CraterImageOptions image;
  ExecutorArguments executor;  // Catalogue: --plan, --executor (docs/cluster.md).
};

// The options that decide a catalogue's result (the detector's, --dtm, --units, --crs), kept in
// an option group so that a plan records them as given (ArgumentsGiven) and run-unit reads them
// again (ParseCratersArguments; throws areomap::Error when they do not parse).
void AddCraterDetectionOptions(CLI::App* group, CratersArgs* args);
CratersArgs ParseCratersArguments(const std::vector<std::string>& arguments);

// args.image with --units and --method applied.
CraterImageOptions ImageOptions(const CratersArgs& args);

// Catalogue mode (two or more rasters, or --list): each image into DIR/images/<NNN>_<stem>/, then
// the merged craters.gpkg, craters.csv, images.csv and summary.json in DIR. Throws
// areomap::Error naming the failed images after writing the others' results.
void RunCraterCatalogue(const CratersArgs& args, const GlobalOptions& global);

// The catalogue as a plan (catalogue_plan.h): writes DIR/plan.json with `arguments` (the
// detection options as given), then hands it to the executor (RunPlan) and prints the merged
// figures when it finished here.
void RunPlannedCraterCatalogue(const CratersArgs& args, const std::vector<std::string>& arguments,
                               const GlobalOptions& global);

// summary.json's own fields of a catalogue (command, mode, list, method, source, files); the
// merge's figures are added to them.
nlohmann::json CatalogueSummaryHead(const CratersArgs& args);

}  // namespace areomap::cli
