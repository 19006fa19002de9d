// The sun azimuth of an image, estimated from its craters' shading when no one gives it.
//
// Lit from azimuth s, a bowl's inner wall on the far side from the sun faces it and is bright,
// the wall on the sun side is in shade (ch. 2.2.1). So the brightness inside a crater, weighted
// by the unit vector from its centre, points away from the sun. Each candidate (detected without
// a sun, so mounds and noise are among them) whose interior shows such a dipole at least
// min_dipole times the surroundings' standard deviation votes for the opposite direction; the
// estimate is the mode of the votes (a von Mises kernel of about 30 degrees over 1 degree steps)
// refined by the circular mean of the votes within 60 degrees of it. Mounds vote the other way
// and scatter; the craters, the majority, agree.
//
// Frame: pixel coordinates (x right, y down) of `image`; azimuth in degrees clockwise from the
// image's up direction, towards the sun, in [0, 360) (the convention of
// CraterDetectorOptions::sun_azimuth_deg).
//
// Failure: never throws for content; too few or disagreeing votes give reliable = false (and
// azimuth NaN when there is no vote). Bad options throw areomap::Error naming the field.
#pragma once

#include <limits>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/map/progress.h"
#include "areomap/map/raster.h"

namespace areomap {

struct SunAzimuthOptions {
  double min_dipole = 0.75;    // a candidate's dipole / surroundings' std to vote
  int min_votes = 5;           // for a reliable estimate
  double min_agreement = 0.6;  // fraction of the votes within 60 degrees of the estimate
  double candidate_min_diameter_px = 16.0;  // EstimateSunAzimuthInRaster's search, overview px
  int overview_size_px = 2048;  // EstimateSunAzimuthInRaster: longest side of the overview
  void Check() const;           // throws areomap::Error naming the field
};

struct SunAzimuthEstimate {
  double azimuth_deg = std::numeric_limits<double>::quiet_NaN();
  int candidates = 0;      // craters looked at
  int votes = 0;           // of them, with a clear dipole
  double agreement = 0.0;  // fraction of the votes within 60 degrees of the estimate
  bool reliable = false;   // votes >= min_votes and agreement >= min_agreement
};

// From craters already found in `image` (single band, CV_32F or convertible; NaN = nodata).
SunAzimuthEstimate EstimateSunAzimuth(const cv::Mat& image,
                                      const std::vector<CraterDetection>& candidates,
                                      const SunAzimuthOptions& options = {});

// Reads band 1 of `dataset` as an overview no longer than options.overview_size_px, finds crater
// candidates on it without a sun (detector's edge settings, upsampling and shading templates
// off) and estimates from them.
SunAzimuthEstimate EstimateSunAzimuthInRaster(const RasterDataset& dataset,
                                              const CraterDetectorOptions& detector,
                                              const SunAzimuthOptions& options = {},
                                              const ProgressCallback& progress = nullptr);

}  // namespace areomap
