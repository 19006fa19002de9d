// The options of `areomap craters` shared by its two modes: one raster (craters_command.cc) and
// a catalogue over many images (craters_catalogue.cc).
#pragma once

#include <string>
#include <vector>

#include "areomap/crater/crater_image.h"
#include "cli_common.h"

namespace areomap::cli {

struct CratersArgs {
  std::vector<std::string> inputs;  // rasters on the command line
  std::string list;                 // --list FILE: more images, one a line
  std::string out_dir;
  std::string units = "px";
  std::string method = "combined";
  std::string crs;  // catalogue: the merged catalogue's CRS (empty: the first image's)
  CraterImageOptions image;
};

// args.image with --units and --method applied.
CraterImageOptions ImageOptions(const CratersArgs& args);

// Catalogue mode (two or more rasters, or --list): each image into DIR/images/<NNN>_<stem>/, then
// the merged craters.gpkg, craters.csv, images.csv and summary.json in DIR. Throws
// areomap::Error naming the failed images after writing the others' results.
void RunCraterCatalogue(const CratersArgs& args, const GlobalOptions& global);

}  // namespace areomap::cli
