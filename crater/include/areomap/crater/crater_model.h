// Crater model from a DTM (ch. 2.3.1): rim shape from the fitted ellipse, depth by both methods
// of ch. 2.2.1, floor radius and the ratios of eqs. 2.2-2.4.
//
// Frame: the rim ellipse is in DTM pixel coordinates (GDAL convention); heights in the DTM's unit
// (metres above the datum); `posting` is the ground size of a DTM pixel in the same unit, so
// lengths below come out in that unit. Per-crater failures (rim off the DTM, too many nodata
// samples) give std::nullopt; bad arguments throw areomap::Error.
#pragma once

#include <optional>

#include <opencv2/core.hpp>

#include "areomap/crater/ellipse.h"

namespace areomap {

struct CraterModel {
  double semi_major = 0.0;         // [m]
  double semi_minor = 0.0;         // [m]
  double mean_radius = 0.0;        // R_avg = (a + b) / 2 [m]
  double eccentricity = 0.0;       // sqrt(1 - b^2 / a^2)
  double rim_height_max = 0.0;     // highest rim-crest sample [m]
  double rim_height_mean = 0.0;    // mean of the rim-crest samples [m]
  double floor_height_min = 0.0;   // lowest point inside 0.9 x the rim [m]
  double floor_height_mean = 0.0;  // mean height of the floor region [m]
  double depth_max_min = 0.0;      // method 1: rim max - floor min [m] (the dissertation's choice)
  double depth_mean = 0.0;         // method 2: rim mean - floor mean [m]
  // Radius of a disc with the floor region's area [m]; the floor region holds the pixels inside
  // 0.9 x the rim lower than floor min + 10 % of the depth (flat floor; small for a bowl).
  double floor_radius = 0.0;
  double ratio1 = 0.0;  // eq. 2.2: semi-minor / semi-major
  double ratio2 = 0.0;  // eq. 2.3: floor radius / R_avg
  double ratio3 = 0.0;  // eq. 2.4: depth (method 1) / R_avg
};

// Measures the crater whose rim crest is `rim_px` on `dtm` (single band, NaN = nodata). The rim
// height at each of 72 points around the ellipse is the highest sample within +-8 % of the
// radius along the ray from the centre (the crest, which the fitted ellipse may miss slightly).
std::optional<CraterModel> MeasureCraterOnDtm(const cv::Mat& dtm, const Ellipse& rim_px,
                                              double posting);

}  // namespace areomap
