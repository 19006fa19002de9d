// Fitting and validating one crater rim from edges, internal to the crater module (the edge
// detector's screening and refinement, crater_detector.cc).
//
// Frame: the pixels of the raster the edges come from (GDAL convention; one pyramid level).
// Failure: std::nullopt where the rim does not validate (too few edges, too little coverage,
// a wrong signature, a failed fit); NaN values where a signature is undefined.
#pragma once

#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/crater/ellipse.h"
#include "areomap/crater/rim_edges.h"

namespace areomap::internal {

// Unit vector towards the sun in pixel coordinates (x right, y down), azimuth clockwise from up;
// none for a DTM or without a sun azimuth.
std::optional<Eigen::Vector2d> SunVector(const CraterDetectorOptions& o, RimSource source);

// The direct ellipse fit of `points`, when it stays near `prior` (centre, mean radius) and
// within `max_axis_ratio`.
std::optional<Ellipse> SaneFit(const std::vector<Eigen::Vector2d>& points, const Ellipse& prior,
                               double max_axis_ratio);

// Image with sun: how well the interior's brightness follows a bowl lit from the sun side
// (far wall bright, near wall dark): Pearson correlation of the samples at elliptical radii
// 0.3-0.8 with -cos(angle to the sun), and the bright-dark contrast of the two walls over the
// surroundings' standard deviation. DTM: (mean rim height - mean interior height) / diameter.
struct SignatureValues {
  double value = std::numeric_limits<double>::quiet_NaN();        // contrast or depth ratio
  double correlation = std::numeric_limits<double>::quiet_NaN();  // image only
};

SignatureValues Signature(const cv::Mat& raster, RimSource source, const Ellipse& e,
                          const std::optional<Eigen::Vector2d>& sun);

// Whether the signature passes the options' threshold; `slack` < 1 relaxes the threshold (a
// pre-screen on a rough ellipse).
bool SignaturePasses(const SignatureValues& s, RimSource source, const CraterDetectorOptions& o,
                     double slack = 1.0);

// Trimmed robust loop on `edges` from `start`, then the geometric fit and validation.
// With `geometric` false the trimmed direct fit is the result (no Ceres, sigmas NaN, residual
// from radial distances): the cheap form used to screen hypotheses.
std::optional<CraterDetection> FitAndValidate(const cv::Mat& raster, const RimEdges& edges,
                                              RimSource source, const Ellipse& start,
                                              const CraterDetectorOptions& o, bool geometric);

}  // namespace areomap::internal
