// Bilinear sampling of single-channel float rasters, internal to the crater module.
//
// Frame: SampleBilinearIndex takes OpenCV index coordinates (x = column, y = row, pixel centres
// at integers); SampleBilinear takes GDAL pixel coordinates (pixel centres at +0.5), as the
// detector's ellipses do. Failure: NaN when the 2 x 2 neighbourhood is not inside `m`; a NaN
// pixel in it gives NaN. `m` must be CV_32F (not checked: callers own their rasters).
#pragma once

#include <cmath>
#include <limits>

#include <opencv2/core.hpp>

namespace areomap::internal {

inline double SampleBilinearIndex(const cv::Mat& m, double x, double y) {
  // Checked before the casts (a NaN or huge coordinate must not reach them).
  if (!(x >= 0.0 && y >= 0.0 && x < m.cols - 1 && y < m.rows - 1)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  // Truncation is the floor of these non-negative coordinates (without a libm call).
  const int c = static_cast<int>(x), r = static_cast<int>(y);
  const double tx = x - c, ty = y - r;
  const float* p0 = m.ptr<float>(r);
  const float* p1 = m.ptr<float>(r + 1);
  return (1 - ty) * ((1 - tx) * p0[c] + tx * p0[c + 1]) + ty * ((1 - tx) * p1[c] + tx * p1[c + 1]);
}

inline double SampleBilinear(const cv::Mat& m, double x, double y) {
  return SampleBilinearIndex(m, x - 0.5, y - 0.5);
}

}  // namespace areomap::internal
