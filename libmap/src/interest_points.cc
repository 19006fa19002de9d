#include "areomap/map/interest_points.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"

namespace areomap {
namespace {

// Förstner's corner location: the point closest, in the least-squares sense, to the lines through
// every window pixel along its edge, (sum g g^T) x = sum g g^T x_i. Falls back to the pixel when
// the system is singular or the solution leaves the window.
Eigen::Vector2d RefinedCorner(const cv::Mat& gx, const cv::Mat& gy, int x, int y, int half) {
  Eigen::Matrix2d normal = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  for (int v = y - half; v <= y + half; ++v) {
    for (int u = x - half; u <= x + half; ++u) {
      const Eigen::Vector2d g(gx.at<float>(v, u), gy.at<float>(v, u));
      const Eigen::Matrix2d ggt = g * g.transpose();
      normal += ggt;
      rhs += ggt * Eigen::Vector2d(u, v);
    }
  }
  const Eigen::Vector2d pixel(x, y);
  if (!(std::abs(normal.determinant()) > 1e-12 * normal.trace() * normal.trace())) return pixel;
  const Eigen::Vector2d refined = normal.ldlt().solve(rhs);
  if (!refined.allFinite() || (refined - pixel).cwiseAbs().maxCoeff() > half) return pixel;
  return refined;
}

}  // namespace

void ForstnerOptions::Check() const {
  const auto require = [](bool ok, const std::string& field, const std::string& expected) {
    if (!ok) throw Error("ForstnerOptions." + field + ": expected " + expected);
  };
  require(half_window >= 1, "half_window", "at least 1 px");
  require(min_roundness >= 0.0 && min_roundness <= 1.0, "min_roundness", "a value in [0, 1]");
  require(weight_factor > 0.0, "weight_factor", "a positive multiple of the mean weight");
  require(suppression_radius_px >= 1, "suppression_radius_px", "at least 1 px");
  require(grid_cells >= 1, "grid_cells", "at least 1");
  require(max_points_per_cell >= 1, "max_points_per_cell", "at least 1");
}

std::vector<InterestPoint> DetectForstnerPoints(const cv::Mat& image,
                                                const ForstnerOptions& options) {
  options.Check();
  if (image.empty() || image.channels() != 1 ||
      (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F)) {
    throw Error(
        "DetectForstnerPoints: expected a non-empty single-channel 8-bit, 16-bit or "
        "float image");
  }
  cv::Mat grey;
  image.convertTo(grey, CV_32F);
  cv::patchNaNs(grey, 0.0);

  cv::Mat gx, gy;
  cv::Sobel(grey, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);  // Scaled to grey levels per pixel.
  cv::Sobel(grey, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  const cv::Size window(2 * options.half_window + 1, 2 * options.half_window + 1);
  cv::Mat nxx, nxy, nyy;
  cv::boxFilter(gx.mul(gx), nxx, CV_32F, window, cv::Point(-1, -1), false);
  cv::boxFilter(gx.mul(gy), nxy, CV_32F, window, cv::Point(-1, -1), false);
  cv::boxFilter(gy.mul(gy), nyy, CV_32F, window, cv::Point(-1, -1), false);

  const cv::Mat det = nxx.mul(nyy) - nxy.mul(nxy);
  const cv::Mat trace = nxx + nyy;
  cv::Mat weight, roundness;
  cv::divide(det, trace, weight);  // 0 where the trace is 0 (OpenCV's division by zero).
  cv::divide(4.0 * det, trace.mul(trace), roundness);

  const double weight_threshold = options.weight_factor * cv::mean(weight)[0];
  cv::Mat local_max;
  const int side = 2 * options.suppression_radius_px + 1;
  cv::dilate(weight, local_max, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(side, side)));

  // Keep away from the border, where the tensor window and the suppression are truncated.
  const int margin = options.half_window + options.suppression_radius_px + 1;
  std::vector<InterestPoint> candidates;
  for (int y = margin; y < grey.rows - margin; ++y) {
    const float* w = weight.ptr<float>(y);
    const float* q = roundness.ptr<float>(y);
    const float* m = local_max.ptr<float>(y);
    for (int x = margin; x < grey.cols - margin; ++x) {
      if (!(w[x] > 0.0f) || w[x] < weight_threshold || w[x] < m[x] ||
          q[x] < options.min_roundness) {
        continue;
      }
      candidates.push_back({RefinedCorner(gx, gy, x, y, options.half_window), w[x], q[x]});
    }
  }
  // Plateaus of w give several maxima for one corner: keep the strongest within the radius.
  std::sort(candidates.begin(), candidates.end(),
            [](const InterestPoint& a, const InterestPoint& b) { return a.weight > b.weight; });
  const int cells = options.grid_cells;
  const double radius = options.suppression_radius_px;
  std::vector<InterestPoint> kept;
  std::vector<int> per_cell(static_cast<size_t>(cells * cells), 0);
  for (const InterestPoint& c : candidates) {
    const bool near_stronger = std::any_of(kept.begin(), kept.end(), [&](const InterestPoint& k) {
      return (k.pixel - c.pixel).norm() <= radius;
    });
    if (near_stronger) continue;
    const int cx = std::clamp(static_cast<int>(c.pixel.x() * cells / grey.cols), 0, cells - 1);
    const int cy = std::clamp(static_cast<int>(c.pixel.y() * cells / grey.rows), 0, cells - 1);
    int& count = per_cell[static_cast<size_t>(cy * cells + cx)];
    if (count >= options.max_points_per_cell) continue;
    ++count;
    kept.push_back(c);
  }
  return kept;
}

}  // namespace areomap
