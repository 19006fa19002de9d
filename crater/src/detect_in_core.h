// Crater detection on one tile of a larger raster, keeping only the craters whose centre lies in
// the tile's core (the rest of the tile is overlap that a neighbouring tile keeps). Internal to
// the crater module (DetectCratersInRaster).
//
// Hypotheses and geometric fits whose centre lies further out of the core than CoreMargin are
// not run. The screening fits move a hypothesis' centre by at most 0.89 r + 2 pixels of its
// pyramid level (SaneFit: 0.35 r + 1 from the arcs' circle of radius r, FitAndValidate: 0.4 x
// the start's radius, at most 1.35 r, + 1), inside the margin's r + 2 level pixels; the
// refinement down the pyramid moves a validated crater by a small fraction of a pixel to a few
// pixels, inside its extra 4 px. Craters that the whole-tile DetectCraters keeps in the core
// are therefore kept (checked on the generated bench tiles: the same detections); duplicates
// across tiles are suppressed by the caller as before.
//
// Frame: pixel coordinates of `raster` (GDAL convention); `core` is [x, x + width) x [y, y +
// height) in those pixels.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "areomap/crater/crater_detector.h"

namespace areomap::internal {

// Largest distance [px] outside the core at which a hypothesis or candidate of radius `radius`
// [px] found on a pyramid level of `scale` full-resolution px per level px is still fitted.
inline double CoreMargin(double radius, double scale) { return radius + 2.0 * scale + 4.0; }

// Largest distance [px] outside the core at which a rim point of such a crater can matter: its
// centre within CoreMargin, moved by the robust fit by up to 1.35 r, plus its radius. Edges
// further out cannot change a crater kept in the core (the upsampled level is searched only
// within it).
inline double RimReach(double radius, double scale) {
  return CoreMargin(radius, scale) + 2.35 * radius;
}

// `d` in the pixels of a raster where its own raster's pixel (x, y) lies at (factor x + dx,
// factor y + dy): centre, axes, their sigmas and the residual scaled, the rest kept.
CraterDetection ShiftedDetection(CraterDetection d, double dx, double dy, double factor);

// DetectCraters restricted to craters centred in `core`; sorted by decreasing confidence.
std::vector<CraterDetection> DetectCratersInCore(const cv::Mat& raster, RimSource source,
                                                 const CraterDetectorOptions& options,
                                                 const cv::Rect2d& core);

}  // namespace areomap::internal
