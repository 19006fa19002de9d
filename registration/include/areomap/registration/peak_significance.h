// How likely is a correlation peak to be a chance alignment? The probability that the highest
// score of a search window at least as high as the peak arises where the template's place is
// not in the window, from the correlation surface itself.
//
// Model (random field theory, Adler 1981; Worsley et al. 1996): at shifts where the template
// does not fit (the null), the NCC surface is a smooth stationary Gaussian field with mean mu,
// standard deviation sigma and, standardised, derivative variances lambda_x, lambda_y per pixel
// of shift. The expected number of chance peaks at least z = (peak - mu) / sigma in a W x H
// window of shifts is its expected Euler characteristic above z:
//
//   E(z) = Q(z) + (W sqrt(lambda_x) + H sqrt(lambda_y)) exp(-z^2/2) / (2 pi)
//              + W H sqrt(lambda_x lambda_y) z exp(-z^2/2) / (2 pi)^(3/2)
//
// (Q the standard normal tail), times the number of templates searched (warps: rotations x
// scales), and the probability of a chance peak is 1 - exp(-warps x E(z)). The field's
// smoothness (lambda: how many independent samples the window holds) follows from the
// template's and the image's autocorrelation through the surface, so a template with broad
// shading features (a smooth surface) gets few independent trials and a textured one many.
//
// The null statistics come from surface pixels at wrong shifts (outside the peak's lobe): tiles
// of the search window, or a ring of windows around a small one (OrbitalMatchOptions::
// null_windows). The orbital matcher measures both the peak and the null on high-passed images
// (broad shading correlates every shift alike). Calibration on real and generated image pairs:
// docs/benchmarks.md, "Registration decision: the false-match probability".
#pragma once

#include <limits>
#include <string>

#include <opencv2/core.hpp>

namespace areomap {

// The null statistics of a correlation surface: its pixels where `null_mask` is nonzero and the
// score is finite.
struct SurfaceNull {
  int samples = 0;                                           // Finite null pixels used.
  double mean = std::numeric_limits<double>::quiet_NaN();    // mu [NCC].
  double stddev = std::numeric_limits<double>::quiet_NaN();  // sigma [NCC].
  // Variances of the standardised surface's first differences along x (columns) and y (rows)
  // [1/px^2]: lambda_x, lambda_y of the header.
  double lambda_x = std::numeric_limits<double>::quiet_NaN();
  double lambda_y = std::numeric_limits<double>::quiet_NaN();

  bool valid() const { return samples > 0 && stddev > 0.0 && lambda_x > 0.0 && lambda_y > 0.0; }
};

// Measures the null statistics of `surface` (CV_32F, NaN where undefined) over the pixels where
// `null_mask` (CV_8U of its size) is nonzero; differences count only where both pixels are null
// pixels. With `block_px` > 0 the standard deviation is the largest of those of the blocks of
// block_px x block_px pixels at least half of whose pixels are null samples (the pooled one
// where no block qualifies): a surface is not stationary, and a window's highest chance peak
// arises where it varies most. Fewer than 2 samples or a flat surface give an invalid result
// (valid() false), never an exception.
SurfaceNull MeasureSurfaceNull(const cv::Mat& surface, const cv::Mat& null_mask, int block_px = 0);

// The significance of a peak.
struct PeakSignificance {
  double z = std::numeric_limits<double>::quiet_NaN();                     // (peak - mu) / sigma.
  double expected_chance_peaks = std::numeric_limits<double>::infinity();  // warps x E(z).
  // 1 - exp(-expected_chance_peaks), in [0, 1]; 1 when the null is invalid or z <= 0.
  double false_match_probability = 1.0;
};

// The probability that a window of `width` x `height` shifts [px of the surface's level],
// searched with `warps` >= 1 templates, holds a chance peak of NCC >= `peak` (formula in the
// header). An invalid null or a non-finite peak gives probability 1.
PeakSignificance SignificanceOfPeak(double peak, const SurfaceNull& null, double width,
                                    double height, int warps = 1);

}  // namespace areomap
