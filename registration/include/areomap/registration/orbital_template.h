// The rover orthophoto resampled onto an orbital image's pixel grid: the template the orbital
// matcher slides over the orbital image (ch. 3.4.2: "the sub-orthophoto was resampled to have
// the same resolution as the HiRISE image").
//
// The orthophoto is low-pass filtered before decimation (a Gaussian whose width in orbital
// pixels is TemplateOptions::lowpass_sigma_orbital_px, about an orbital camera's MTF, so both
// images carry the same band), nodata-aware by normalized convolution (blur of value x mask
// divided by blur of mask), then sampled bilinearly at the orbital pixel centres. Only the
// reliable range around the rover is kept (80 m by default: Pancam/Navcam stereo error
// exceeds ~2 m beyond it, ch. 3.4.2).
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_image.h"

namespace areomap {

struct TemplateOptions {
  double reliable_range_m = 80.0;  // Ortho pixels farther from the rover are dropped [m]; 0 = all.
  double lowpass_sigma_orbital_px = 0.5;  // Anti-alias Gaussian [orbital px], >= 0.
  double min_coverage = 0.9;  // A template pixel is valid if >= this fraction of its filter
                              // footprint is valid ortho pixels, in (0, 1].
  int lattice_step_px = 8;    // Exact CRS mapping every this many template pixels, >= 1.

  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

// The template on the orbital grid, at the orthophoto's own (telemetry) georeference.
struct OrbitalTemplate {
  cv::Mat image;    // CV_32FC1, NaN where invalid.
  cv::Mat mask;     // CV_8UC1, nonzero = valid.
  int col0 = 0;     // Orbital pixel column of template pixel (0, 0).
  int row0 = 0;     // Orbital pixel row of template pixel (0, 0).
  cv::Mat ortho_x;  // CV_32FC1: ortho pixel coordinate (GDAL convention) sampled at each
  cv::Mat ortho_y;  //   template pixel centre; NaN where the CRSs cannot map.
  int valid_pixels = 0;
  double scale = 1.0;  // Orbital pixel size / ortho pixel size.

  bool empty() const { return valid_pixels == 0; }
};

// Resamples `ortho` (its grid `ortho_grid`) onto `orbital_grid`, keeping the pixels within the
// reliable range of `rover_in_ortho_px` (ortho pixel coordinates of the rover). An orthophoto
// with no valid pixel in range gives an empty template (valid_pixels = 0), not an exception.
// Throws areomap::Error if the options fail Check() or the ortho image is not CV_32FC1.
OrbitalTemplate ResampleToOrbitalGrid(const OrthoImage& ortho, const PixelGrid& ortho_grid,
                                      const PixelGrid& orbital_grid,
                                      const Eigen::Vector2d& rover_in_ortho_px,
                                      const TemplateOptions& options = {});

}  // namespace areomap
