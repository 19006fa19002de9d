// One detected crater: its rim ellipse with 1-sigma, the evidence it was accepted on, and how it
// was measured. The result type of every detector (crater_detector.h for rim edges on images and
// DTMs, learned_detector.h for the network) and of the crater readers and writers.
//
// Frame: pixel coordinates of the input raster, GDAL convention (pixel (col, row) covers
// [col, col + 1) x [row, row + 1)), x right, y down; lengths in pixels, angles in radians from
// +x towards +y.
#pragma once

#include <limits>

#include "areomap/crater/ellipse.h"

namespace areomap {

struct CraterDetection {
  Ellipse ellipse;  // rim crest [px]
  // 1-sigma from the geometric fit's covariance [px, rad] (the fit uses at most 128 rim edges,
  // evenly spread); NaN where not available.
  double center_x_sigma = 0.0;
  double center_y_sigma = 0.0;
  double semi_major_sigma = 0.0;
  double semi_minor_sigma = 0.0;
  double angle_sigma = 0.0;
  double rms_residual = 0.0;  // RMS orthogonal distance of the rim edges [px]
  double efs = 0.0;           // Ellipse-Fit-Similarity, eq. 2.1
  double coverage = 0.0;      // fraction of 36 rim sectors holding an edge near the rim
  // Image: (inner wall facing the sun - wall facing away) / surroundings' std; DTM: (mean rim
  // height - mean height inside half the radius) / diameter [height unit per px]. NaN for an
  // image without sun azimuth.
  double signature = 0.0;
  // Image with sun: correlation of the interior brightness with a bowl's shading pattern
  // (-cos of the angle to the sun) in [-1, 1]; NaN otherwise.
  double shading_correlation = 0.0;
  double confidence = 0.0;  // in [0, 1]: coverage x signature strength x fit quality
  bool partial = false;     // coverage < 0.6 or the rim leaves the raster
  int num_edge_points = 0;
  double edge_contrast = 0.0;  // mean strength of the rim edges / the high Canny threshold  //
                               // edges used by the final fit
  int pyramid_level = 0;       // level where the crater was found (0 = full resolution)
  // false: the learned detector's circle, kept because the rim showed too few edges for an
  // ellipse fit; the sigmas then are the network's measured errors (learned_detector.h).
  bool rim_fitted = true;
  double model_score = std::numeric_limits<double>::quiet_NaN();  // learned heat-map peak
  // Found by the rim-edge detector (crater_detector.h); false for a crater only the network
  // found (then model_score is its evidence).
  bool edge_detected = true;

  double Diameter() const { return ellipse.semi_major + ellipse.semi_minor; }  // [px]
};

}  // namespace areomap
