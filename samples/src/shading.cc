#include "shading.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "areomap/map/geodesy.h"

namespace areomap::internal {

// Unit vector toward the sun in ENU.
Eigen::Vector3d SunDirection(double azimuth_deg, double elevation_deg) {
  const double az = RadFromDeg(azimuth_deg);
  const double el = RadFromDeg(elevation_deg);
  return {std::cos(el) * std::sin(az), std::cos(el) * std::cos(az), std::sin(el)};
}

// Cast shadows on a north-up height grid (row 0 = north): a pixel is shadowed when the terrain
// toward the sun rises above the sun's ray. One sweep in order of distance toward the sun,
// carrying the height of the "shadow surface" (Horn 1981's sweep, on an arbitrary azimuth).
cv::Mat ShadowMask(const cv::Mat& heights, double cell_m, const Eigen::Vector3d& sun) {
  const int rows = heights.rows, cols = heights.cols;
  const Eigen::Vector2d toward(sun.x(), -sun.y());  // In (col, row) units: north is -row.
  const Eigen::Vector2d dir = toward.normalized();
  const double step_px = 1.5;  // Predecessor's bilinear corners all lie strictly sunward.
  const double drop = step_px * cell_m * sun.z() / std::hypot(sun.x(), sun.y());
  std::vector<int> order(static_cast<size_t>(rows) * cols);
  std::iota(order.begin(), order.end(), 0);
  std::vector<double> key(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    key[i] = (static_cast<double>(i % cols) * dir.x() + static_cast<double>(i / cols) * dir.y());
  }
  std::sort(order.begin(), order.end(), [&](int a, int b) { return key[a] > key[b]; });
  cv::Mat surface = heights.clone();  // CV_64F
  cv::Mat shadow = cv::Mat::zeros(rows, cols, CV_8U);
  for (int index : order) {
    const int r = index / cols, c = index % cols;
    const double pc = c + step_px * dir.x(), pr = r + step_px * dir.y();
    if (pc < 0.0 || pr < 0.0 || pc > cols - 1.0 || pr > rows - 1.0) continue;
    const int c0 = std::min(static_cast<int>(pc), cols - 2),
              r0 = std::min(static_cast<int>(pr), rows - 2);
    const double fc = pc - c0, fr = pr - r0;
    const double ahead =
        (1 - fr) * ((1 - fc) * surface.at<double>(r0, c0) + fc * surface.at<double>(r0, c0 + 1)) +
        fr * ((1 - fc) * surface.at<double>(r0 + 1, c0) + fc * surface.at<double>(r0 + 1, c0 + 1));
    const double ray = ahead - drop;
    double& here = surface.at<double>(r, c);
    if (ray > here) {
      here = ray;
      shadow.at<uchar>(r, c) = 1;
    }
  }
  return shadow;
}

}  // namespace areomap::internal
