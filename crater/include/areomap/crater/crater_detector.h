// Multi-crater detection: rim edges -> arcs -> ellipse hypotheses -> robust fit -> validation.
//
// Pipeline (per pyramid level, each level halving the resolution by 2x2 box averaging, plus a
// 2x upsampled level for craters under 16 px across):
//  1. Rim edges (rim_edges.h): sub-pixel Canny edges with gradient direction for an image,
//     curvature crests for a DTM.
//  2. Arcs: 8-connected edge pixels whose normals lie within a 90 degree window (12 overlapping
//     windows, so a rim falls into several arcs), built from edges at least half as strong as
//     the rim threshold (min_edge_contrast x high Canny threshold). Each arc estimates its circle
//     centre as the least-squares intersection of its normals, its radius and its polarity
//     (gradient pointing out of or into the circle). With a known sun, arcs whose polarity
//     contradicts the shading of a bowl (brightness must rise towards the sun across the rim,
//     ch. 2.2.1) are dropped: this removes the shadow edge on the floor and positive relief
//     (mounds).
//  3. Hypotheses: arcs whose centres and radii agree are grouped; groups of weak edges, and
//     groups whose rough circle shows less than half the required bowl signature, are dropped
//     at once; the group's points seed FitEllipseFast (one OpenCV algebraic fit). A trimmed
//     robust loop then gathers all edges near the ellipse with a normal aligned to it (giving
//     up when they cover under 3/4 of min_coverage), refits, and repeats until it converges.
//  4. Validation: mean rim edge strength over the high Canny threshold, the signature of a bowl
//     (for an image with known sun azimuth the inner wall facing the sun must be brighter than
//     the one facing away; for a DTM the interior must lie below the rim), sector coverage and
//     fit residual.
//  5. Candidates of all levels are compared in full-resolution pixels and duplicates
//     suppressed; each remaining crater is refined down the pyramid on the finer levels' edges
//     (unless refine_to_full_resolution is false) and gets one orthogonal-distance fit with a Huber
//     loss (RefineEllipseGeometric, Ceres) on the finest level where it validates, then duplicates
//     are suppressed again.
//
// Frame: pixel coordinates of the input, GDAL convention (pixel (col, row) covers
// [col, col + 1) x [row, row + 1)), x right, y down; lengths in pixels, angles in radians from
// +x towards +y. Sun azimuth: degrees clockwise from the image's up direction (north for a
// north-up map), towards the sun.
//
// Failure: bad options throw areomap::Error naming the field. Image content never throws: an
// image without craters, a constant image or one full of nodata gives an empty result.
//
// Accuracy and speed against the labelled real images: docs/benchmarks.md (craters).
#pragma once

#include <limits>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/crater/crater_detection.h"
#include "areomap/crater/ellipse.h"
#include "areomap/crater/learned_options.h"
#include "areomap/crater/rim_edges.h"
#include "areomap/crater/shading_hypotheses.h"
#include "areomap/map/progress.h"

namespace areomap {

enum class RimSource {
  kImage,  // brightness: Canny edges, shading signature when the sun azimuth is known
  kDtm,    // heights: curvature crests, depth signature
};

struct CraterDetectorOptions {
  static constexpr double kSmallestDiameterPx = 4.0;  // the least min_diameter_px accepted
  // Limits of the rim diameter a + b reported [px]; the search reaches 10 % beyond them, so that
  // a crater measured near a limit on a coarse level is not lost before its final fit. The
  // learned detector keeps a circle without a rim fit that meets them within 2 sigma of its
  // diameter (learned_detector.h).
  double min_diameter_px = 8.0;           // >= kSmallestDiameterPx
  double max_diameter_px = 0.0;           // 0: no limit besides the raster size
  std::optional<double> sun_azimuth_deg;  // image only; enables the shading checks
  EdgeOptions edges;
  double min_coverage = 0.4;  // of 36 rim sectors
  // Image with sun: signature threshold. A fresh crater's walls (slopes of 25-40 degrees) are
  // several times brighter/darker than gently rolling plains; 2.5 keeps shallow depressions of
  // the background out.
  double min_shading_contrast = 2.5;
  // Rim edges must be a sharp break: mean edge strength >= this x the high Canny threshold.
  double min_edge_contrast = 2.0;
  // DTM: signature threshold [height unit / px]; fresh simple craters have depth/diameter
  // about 0.2, degraded ones down to about 0.05.
  double min_depth_ratio = 0.06;
  double max_axis_ratio = 1.6;  // a / b
  // Search craters below 16 px across on a 2x upsampled copy (about 2.5x the work).
  bool upsample_small_craters = true;
  // Images: search the upsampled copy only around the full-resolution arcs whose circles are
  // under ~19 px across and whose edges are as strong on average as a rim's must be (0.8 x
  // min_edge_contrast x the high Canny threshold), and in a tile only within reach of its core; a
  // small crater that can pass the edge contrast test shows such an arc already at full
  // resolution. false: the whole copy (DTMs always), about 2x the time (docs/benchmarks.md).
  bool upsample_only_around_small_arcs = true;
  // false: each crater gets its geometric fit on the pyramid level where it was found, not
  // refined down to full resolution (for a caller that refines it itself, e.g. the overview of
  // DetectCratersInRaster).
  bool refine_to_full_resolution = true;
  double dtm_posting = 1.0;  // DTM: ground size of a pixel in height units
  int tile_size = 2048;      // DetectCratersInRaster: tile core edge [px]
  int tile_overlap = 128;    // and margin [px]; bounds in-tile diameters
  // Image with sun: bowl-shading template hypotheses (shading_hypotheses.h) for small or
  // degraded craters whose rims show edges only along the sun line; each is first tried as a
  // start for the edge fit and validation above, then accepted on its own evidence.
  ShadingTemplateOptions shading_template;
  // DetectCratersInRaster on an image: the edge pipeline above (default) or the learned detector
  // (learned_detector.h; docs/crater-model.md says where each is better); DTMs and DetectCraters
  // always use the edges.
  CraterMethod method = CraterMethod::kCombined;
  LearnedDetectorOptions learned;

  void Check() const;  // throws areomap::Error naming the bad field
  // Whether detection searches the 2x upsampled level: upsample_small_craters is on and craters
  // under 16 px across are asked for (min_diameter_px < 16). Its images and edge temporaries hold
  // four times the input's pixels.
  bool SearchesUpsampledLevel() const;
};

// Detects craters in one in-memory raster (single band, any depth, NaN = nodata). Sorted by
// decreasing confidence. Progress per pyramid level; cancelling throws areomap::Error.
std::vector<CraterDetection> DetectCraters(const cv::Mat& raster, RimSource source,
                                           const CraterDetectorOptions& options = {},
                                           const ProgressCallback& progress = nullptr);

// Re-fits one crater on `raster` starting from `initial` [px of `raster`]: edges near the
// ellipse, trimmed direct fit, geometric fit, validation. nullopt when it does not validate.
std::optional<CraterDetection> RefineCrater(const cv::Mat& raster, RimSource source,
                                            const Ellipse& initial,
                                            const CraterDetectorOptions& options = {});

// The detections whose diameter lies within options' min_diameter_px and max_diameter_px (0: no
// upper limit), in their order.
std::vector<CraterDetection> KeepWithinDiameterLimits(std::vector<CraterDetection> detections,
                                                      const CraterDetectorOptions& options);

// Suppresses duplicates, keeping the more confident of two detections when their centres are
// closer than half the smaller mean radius and their diameters agree within 30 %, or when one is
// concentric (centre distance < 0.3 x the larger radius) with diameters within a factor 1.6 (the
// floor or shadow edge inside a rim); of equally confident ones, the first in `detections`.
// Sorted by decreasing confidence, equal confidences in their input order.
std::vector<CraterDetection> SuppressDuplicateCraters(std::vector<CraterDetection> detections);

}  // namespace areomap
