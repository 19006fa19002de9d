// The merge step of a crater catalogue over many images: the image folders that
// RunCraterCatalogueImage wrote (crater_catalogue.h) become one catalogue in ground coordinates,
// each crater once where images overlap.
//
// Frame: one common projected Mars CRS in metres, the first merged image's (or the one given);
// craters of an image in another CRS are moved into it by OGR/PROJ (centres and rim polygons),
// their metres scaled by the transformation's local area scale at the centre.
// Same crater: SameCraterEitherWay (same_crater.h) on centres and rim diameters in metres of
// the common CRS, over every pair of craters (across and within images), found through a
// quadtree on the centres (GDAL's CPLQuadTree): O(n log n) for n craters; memory about 100
// bytes a crater plus one image's features at a time (docs/crater-catalogue.md).
// Which of two is kept, the better-fitted rim, in this order:
//  1. a complete rim over a partial one (under 60 % of the rim's sectors hold edges, or the rim
//     leaves its image): where images overlap, a crater cut by one image's edge lies whole in
//     the other, and only there is its fit constrained all round;
//  2. an ellipse fitted to rim edges over the learned detector's circle (rim_fitted 0);
//  3. the smaller centre 1-sigma relative to the diameter, hypot(sx, sy) / D in pixels of its
//     image: how tightly the rim constrains the fit, free of scale so that it compares images of
//     different pixel sizes (NaN counts as worst);
//  4. the earlier image in the list, then the earlier crater in it (determinism).
// Greedy in that order: a crater is kept unless it is the same crater as one kept before it.
//
// Outputs in out_dir, each written atomically: craters.gpkg (layer "craters": rim polygons in
// the common CRS), craters.csv (the same attributes, no geometry) and images.csv (one row per
// image folder: folder, image, status, craters detected, kept, duplicates removed, seconds,
// error). Attributes: id (1.., in image then crater order), source_image (path as given),
// source_folder, source_id (the crater's id in its image's catalogue), diameter_m, then every
// column of the image's craters.csv with map_x, map_y, semi_major_m, semi_minor_m in the common
// CRS (pixel columns stay in the source image's pixels). CSV text fields holding a comma or a
// quote are quoted (RFC 4180).
// Failure: a folder without image.json, an "ok" image whose craters.gpkg is missing or
// unreadable, a common CRS that is not a projected Mars CRS in metres, or an unwritable out_dir
// throw areomap::Error naming the file. Failed images are rows of images.csv, not errors; with
// no image ok, craters.gpkg is not written.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/progress.h"

namespace areomap {

struct CatalogueMergeOptions {
  // The common CRS (anything Crs::FromUserInput takes: "IAU_2015:49910", WKT, a PROJ string);
  // empty: the CRS of the first image that is ok.
  std::string crs;
};

struct CatalogueImageRow {
  std::string folder;  // the image folder's name
  std::string image;   // the raster's path as given
  bool ok = false;
  std::string error;           // why it failed; empty when ok
  int detected = 0;            // craters in the image's catalogue
  int kept = 0;                // of those, in the merged catalogue
  int duplicates_removed = 0;  // detected - kept
  double seconds = 0.0;        // the image job's wall time [s]
};

struct CatalogueMergeSummary {
  std::vector<CatalogueImageRow> images;  // in the order of the folders given
  int images_ok = 0;
  int images_failed = 0;
  int detected = 0;
  int kept = 0;
  int duplicates_removed = 0;
  std::string crs_name;  // the common CRS; empty when no image is ok
  double seconds = 0.0;  // the merge's wall time [s]
};

// Merges the image folders (RunCraterCatalogueImage's, in list order) into out_dir (an
// existing folder). Progress per image read, twice (the search, then the writing).
CatalogueMergeSummary MergeCraterCatalogues(const std::vector<std::filesystem::path>& image_dirs,
                                            const std::filesystem::path& out_dir,
                                            const CatalogueMergeOptions& options = {},
                                            const ProgressCallback& progress = nullptr);

// The figures of a merge as summary.json holds them (images, ok, failed, craters detected, kept,
// duplicates removed, CRS, seconds, the failed images with their errors).
nlohmann::json CatalogueMergeSummaryJson(const CatalogueMergeSummary& summary);

}  // namespace areomap
