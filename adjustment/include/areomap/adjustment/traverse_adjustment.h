// The whole adjustment job behind `areomap adjust`: read the JSON inputs, adjust, anchor, write
// every product into one folder. Files written (atomically) into `out_dir`:
//   adjustment.json  BundleResult (sigma0, per-site poses and 6x6 covariances, per-observation
//                    chi2 and residuals, rejections with reasons)
//   report.txt       the same for people: summary, sites, rejected observations, leg table
//   sites.csv, legs.csv, traverse.gpkg (traverse_products.h)
//   traverse_map.png when an orbital image is given
// Failure: bad input throws areomap::Error (bundle_io.h) before anything is written.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/adjustment/bundle_adjustment.h"
#include "areomap/adjustment/bundle_io.h"
#include "areomap/adjustment/traverse_anchoring.h"
#include "areomap/adjustment/traverse_products.h"
#include "areomap/map/progress.h"

namespace areomap {

struct TraverseAdjustmentOptions {
  BundleOptions bundle;
  // Multiplies the covariances of the rock tie points (source "rock") read from the inputs: the
  // observation group's a-posteriori variance factor (a run: its legs' pooled sigma_0^2,
  // mission_run.h, which reports it). 1 keeps them as written; Check() throws unless finite and
  // > 0.
  double rock_tie_variance_factor = 1.0;
  std::filesystem::path orbital_image;  // Empty: no traverse map.
  TraverseMapOptions map;
  void Check() const;
};

// Readable report of an adjustment (a few lines per section).
std::string ReadableReport(const BundleResult& result, const AnchoredTraverse& traverse);

// Runs the job and returns the key figures (what summary.json holds besides "command").
// `out_dir` must exist. Throws areomap::Error, before writing anything, for bad options, an
// unreadable input (ReadBundleInput) or a missing orbital image.
nlohmann::json AdjustTraverse(const std::vector<std::filesystem::path>& inputs,
                              const std::filesystem::path& out_dir,
                              const TraverseAdjustmentOptions& options,
                              const ProgressCallback& progress = nullptr);
// Same from inputs already read (so that a caller can validate them before creating `out_dir`).
nlohmann::json AdjustTraverseInput(BundleInputFile file, const std::filesystem::path& out_dir,
                                   const TraverseAdjustmentOptions& options,
                                   const ProgressCallback& progress = nullptr);

}  // namespace areomap
