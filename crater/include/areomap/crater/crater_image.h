// The crater job on one raster, as `areomap craters IMAGE --out DIR` runs it: open the raster,
// turn the diameter limits into pixels, choose the sun azimuth (given, or estimated from the
// image's shading), detect (DetectCratersInRaster), measure crater models on a DTM, and write
// craters.csv, craters.json, craters.gpkg (georeferenced rasters only) and overlay.png.
// The catalogue over many images (crater_catalogue.h) runs the same job per image.
//
// Two steps, so that every option and input problem is reported before an output folder is
// touched: PrepareCraterImage (reads the raster's header, and its pixels only to estimate the
// sun) and DetectCraterImage (the detection and the files).
// Frame and units: crater_output.h (pixels of the raster, GDAL convention; map coordinates of its
// CRS; metres from its geotransform).
// Failure: a missing or unreadable raster or model, a CRS not on Mars, and options that cannot
// apply to this raster throw areomap::Error naming the file or the option and what is expected.
// Nothing is printed: notes and warnings are returned for the caller to show.
// The command's options and outputs: docs/cli.md (`areomap craters`).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/crater/sun_azimuth.h"
#include "areomap/map/progress.h"
#include "areomap/map/raster.h"

namespace areomap {

struct CraterImageOptions {
  // Detector settings; its method (forced to kEdges for a DTM), min_diameter_px,
  // max_diameter_px, dtm_posting and sun_azimuth_deg are set from the fields below.
  CraterDetectorOptions detector;
  bool dtm = false;                  // the raster holds heights: curvature crests, crater models
  bool diameters_in_metres = false;  // min_diameter, max_diameter in m (projected CRS), else px
  double min_diameter = 8.0;         // smallest rim diameter [px or m], >= 4 px
  double max_diameter = 0.0;         // largest rim diameter [px or m]; 0: no limit
  // [deg clockwise from image up]: enables the shading checks. Unset: estimated from the image's
  // craters (estimate_sun), else the checks stay off.
  std::optional<double> sun_azimuth_deg;
  bool estimate_sun = true;
  // Refuse a raster without ground positions (a geotransform and a projected Mars CRS in
  // metres), as a catalogue over many images must.
  bool require_ground = false;
  int overlay_max_side = 4096;  // longer side of overlay.png at most [px]

  // Throws areomap::Error naming the field or the option that does not fit the others (shading
  // templates with the learned method or a DTM). Reads no file.
  void Check() const;
};

// Loads the network `options` would use (an image with a learned or combined method): throws
// areomap::Error naming the model file when it is missing or not a crater model; nothing to do
// for the edges or a DTM. PrepareCraterImage calls it; a caller running many images calls it
// once before the first.
void CheckCraterModel(const CraterImageOptions& options);

// A raster ready for detection.
struct CraterImageJob {
  CraterImageJob(std::filesystem::path image_path, RasterDataset opened)
      : image(std::move(image_path)), dataset(std::move(opened)) {}

  std::filesystem::path image;
  RasterDataset dataset;
  RimSource source = RimSource::kImage;
  CraterDetectorOptions detector;  // resolved: method, limits in px, posting, sun azimuth
  bool dtm = false;
  std::string model;          // the network used: "built-in", a path, or "" for kEdges
  double pixel_size_m = 0.0;  // ground size of a pixel; 0 when not in a projected CRS
  bool georeferenced = false;
  int overlay_max_side = 4096;
  // Where options.sun_azimuth_deg came from: "given", "estimated", "none", "none (DTM)".
  std::string sun_azimuth_source;
  std::optional<SunAzimuthEstimate> sun_estimate;  // when one was made
  std::vector<std::string> notes;                  // e.g. the estimated sun azimuth, for people
  std::vector<std::string> warnings;  // e.g. no sun could be estimated: more false detections
};

// What DetectCraterImage found and wrote.
struct CraterImageResult {
  int craters = 0;
  int partial = 0;
  int rims_fitted = 0;
  int edge_detected = 0;
  int64_t valid_pixels = 0;           // finite, not nodata
  std::vector<std::string> files;     // written into out_dir, summary.json not included
  std::vector<std::string> warnings;  // e.g. no valid pixel: nothing was searched
};

// Opens `image` and resolves `options` for it; estimates the sun azimuth when none is given
// (progress reports that estimate). Throws as above.
CraterImageJob PrepareCraterImage(const std::filesystem::path& image,
                                  const CraterImageOptions& options,
                                  const ProgressCallback& progress = nullptr);

// Detects the craters of `job` and writes craters.csv, craters.json, craters.gpkg (when
// georeferenced) and overlay.png into `out_dir` (an existing folder), each atomically.
CraterImageResult DetectCraterImage(const CraterImageJob& job, const std::filesystem::path& out_dir,
                                    const ProgressCallback& progress = nullptr);

// The summary.json of `areomap craters IMAGE` (command, input, method, counts, sun, files).
nlohmann::json CraterImageSummaryJson(const CraterImageJob& job, const CraterImageResult& result);

}  // namespace areomap
