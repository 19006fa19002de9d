// Learned crater detection on images: a small centre-point network (CenterNet-style) trained on
// labelled real Mars images, run through OpenCV dnn on an image pyramid, each detection then
// refined by the rim ellipse fit of crater_detector.h where the rim shows edges.
//
// The network sees a locally contrast-normalised image (any gain, offset and bit depth) and
// predicts, on a grid of half the input's resolution, a crater-centre heat map, the centre's
// offset and the rim diameter. Level l of the pyramid (2^l x 2^l box averages) finds craters of
// 12-24 px of that level (level 0: under 24 px) and also reports those of 9.6-12 px, so that a
// crater near a band edge is not lost between two levels (duplicates suppressed); the work is 4/3
// of one full-resolution pass. Levels run in tiles with a margin wider than
// the network's reach, so a tiled raster gives the same craters as a whole one. The model, its
// training data and its scores: docs/crater-model.md; retraining: scripts/crater_model/train.py.
//
// Frame: full-resolution pixel coordinates (GDAL convention, as DetectCraters), lengths in px.
// Failure: a missing or unreadable model file throws areomap::Error naming it; image content
// never throws (constant images, nodata and tiny rasters give no or fewer craters).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/crater/crater_score.h"
#include "areomap/crater/learned_options.h"
#include "areomap/map/progress.h"
#include "areomap/map/raster.h"

namespace areomap {

// The network, loaded once; each Forward call is independent. Not safe to call from two threads
// at once (OpenCV dnn); it parallelises internally.
class CraterNetwork {
 public:
  // Loads `model_path`, or the built-in model when empty. Throws areomap::Error naming the file
  // when it is missing or not a model OpenCV dnn can read with the expected input and outputs.
  explicit CraterNetwork(const std::string& model_path = "");
  ~CraterNetwork();
  CraterNetwork(CraterNetwork&&) noexcept;
  CraterNetwork& operator=(CraterNetwork&&) noexcept;

  struct Output {
    // On the half-resolution grid of the input, cell (i, j) centred on input pixel centre
    // (2j + 1, 2i + 1); each CV_32F of (rows / 2, cols / 2).
    cv::Mat heat;          // crater-centre score in [0, 1]
    cv::Mat dx, dy;        // centre offset from the cell centre [cells]
    cv::Mat log_diameter;  // log(D / 8 px)
  };
  // `normalized`: CV_32F from NormalizeForCraterNetwork, rows and cols multiples of 8.
  Output Forward(const cv::Mat& normalized);
  const std::string& source() const;  // the model file, or "built-in"

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Local contrast normalisation the network expects: (x - mean) / std over a 31 px box
// (reflected border), clipped to +-4; NaN pixels become 0 (the local mean).
cv::Mat NormalizeForCraterNetwork(const cv::Mat& image);

// Detects craters in band 1 of `dataset` (any size: read by windows, memory bounded by a few
// tiles). A raster over 64 MB as Float32 also takes about a third of its Float32 size on the
// temporary folder's disk for its pyramid levels, in files unlinked at once (without room there it
// reads the levels from the raster, slower). Diameter limits from `options` (min_diameter_px,
// max_diameter_px): fitted rims within them, circles without a rim fit within them or within
// 2 sigma of their diameter (never under 4 px), as the network's diameters regress towards the
// middle of its range (docs/crater-model.md). The rim fits use `options`' edge settings. Sorted by
// decreasing confidence (the heat-map peak). Progress per tile; cancelling throws areomap::Error.
std::vector<CraterDetection> DetectCratersLearned(const RasterDataset& dataset,
                                                  const CraterDetectorOptions& options,
                                                  const LearnedDetectorOptions& learned = {},
                                                  const ProgressCallback& progress = nullptr);

// Where the network sees craters: what the combined detector asks of an edge rim.
struct NetworkSupport {
  // Heat-map peaks >= LearnedDetectorOptions::edge_support_score [full-resolution px].
  std::vector<CraterCircle> circles;
  // Rims wider than this [px] lie beyond the coarsest pyramid level's reach and need no support;
  // 0 (edge_support_score 0) asks none of any rim.
  double reach_px = 0.0;
};

// The combined detector's result (CraterMethod::kCombined): every rim of the edge detector that
// `support` confirms (a circle of it SameCraterOrConcentric with the rim, or the rim wider than
// support.reach_px), plus each of the network's craters that is not one of them (centres closer
// than a quarter of the larger diameter and diameters within 30 %: the scoring rule's tolerance,
// crater_score.h) nor inside one (under 0.7 of its diameter, centred within 3/4 of its radius: a
// floor, shadow or slump the network took for a crater). An edge rim the network also found
// takes its model_score. The edge detector's rims come first (their ellipses and sigmas are
// fitted on the rim edges), then the network's own finds, each in its input order. Rationale and
// scores: docs/crater-model.md.
std::vector<CraterDetection> MergeEdgeAndLearnedCraters(std::vector<CraterDetection> edges,
                                                        const std::vector<CraterDetection>& learned,
                                                        const NetworkSupport& support);

// The same on an in-memory image (single band, any depth, NaN = nodata).
std::vector<CraterDetection> DetectCratersLearned(const cv::Mat& image,
                                                  const CraterDetectorOptions& options,
                                                  const LearnedDetectorOptions& learned = {},
                                                  const ProgressCallback& progress = nullptr);

}  // namespace areomap
