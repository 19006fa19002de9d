#include "areomap/registration/orbital_template.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"

namespace areomap {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Mean pixel edge [m] of a grid at `pixel`.
double PixelSizeM(const PixelGrid& grid, const Eigen::Vector2d& pixel) {
  const Eigen::Matrix2d m = grid.EastNorthPerPixel(pixel);
  return 0.5 * (m.col(0).norm() + m.col(1).norm());
}

// Valid ortho pixels within `range_m` of the rover.
cv::Mat ValidInRange(const OrthoImage& ortho, const PixelGrid& grid, const Eigen::Vector2d& rover,
                     double range_m) {
  cv::Mat valid = ortho.ValidMask();
  if (range_m <= 0.0) return valid;
  const Eigen::Matrix2d en = grid.EastNorthPerPixel(rover);
  if (!en.allFinite()) {
    throw Error(ortho.source + ": the rover position lies outside the CRS's domain");
  }
  const double range2 = range_m * range_m;
  tbb::parallel_for(0, valid.rows, [&](int r) {
    auto* row = valid.ptr<uchar>(r);
    for (int c = 0; c < valid.cols; ++c) {
      const Eigen::Vector2d d = en * Eigen::Vector2d(c + 0.5 - rover.x(), r + 0.5 - rover.y());
      if (d.squaredNorm() > range2) row[c] = 0;
    }
  });
  return valid;
}

}  // namespace

void TemplateOptions::Check() const {
  RequireOption(std::isfinite(reliable_range_m) && reliable_range_m >= 0.0,
                "TemplateOptions.reliable_range_m", ">= 0 m (0 keeps every pixel)");
  RequireOption(std::isfinite(lowpass_sigma_orbital_px) && lowpass_sigma_orbital_px >= 0.0,
                "TemplateOptions.lowpass_sigma_orbital_px", ">= 0 orbital pixels");
  RequireOption(min_coverage > 0.0 && min_coverage <= 1.0, "TemplateOptions.min_coverage",
                "in (0, 1]");
  RequireOption(lattice_step_px >= 1, "TemplateOptions.lattice_step_px", ">= 1");
}

OrbitalTemplate ResampleToOrbitalGrid(const OrthoImage& ortho, const PixelGrid& ortho_grid,
                                      const PixelGrid& orbital_grid,
                                      const Eigen::Vector2d& rover_in_ortho_px,
                                      const TemplateOptions& options) {
  options.Check();
  if (ortho.image.empty() || ortho.image.type() != CV_32FC1) {
    throw Error(ortho.source + ": the orthophoto image must be a non-empty CV_32FC1 band");
  }
  OrbitalTemplate out;
  const cv::Mat valid =
      ValidInRange(ortho, ortho_grid, rover_in_ortho_px, options.reliable_range_m);
  std::vector<cv::Point> points;
  cv::findNonZero(valid, points);
  if (points.empty()) return out;
  const cv::Rect box = cv::boundingRect(points);

  // Footprint of the valid box on the orbital grid (its outline, densely: CRSs may rotate).
  const GridMapping to_orbital(ortho_grid, orbital_grid);
  double min_c = std::numeric_limits<double>::infinity(), max_c = -min_c;
  double min_r = min_c, max_r = -min_c;
  const int steps = 16;
  for (int k = 0; k <= steps; ++k) {
    const double t = static_cast<double>(k) / steps;
    const double x0 = box.x, x1 = box.x + box.width, y0 = box.y, y1 = box.y + box.height;
    for (const Eigen::Vector2d& p :
         {Eigen::Vector2d(x0 + t * (x1 - x0), y0), Eigen::Vector2d(x0 + t * (x1 - x0), y1),
          Eigen::Vector2d(x0, y0 + t * (y1 - y0)), Eigen::Vector2d(x1, y0 + t * (y1 - y0))}) {
      const Eigen::Vector2d q = to_orbital.Apply(p);
      if (!q.allFinite()) continue;
      min_c = std::min(min_c, q.x());
      max_c = std::max(max_c, q.x());
      min_r = std::min(min_r, q.y());
      max_r = std::max(max_r, q.y());
    }
  }
  if (!(max_c > min_c) || !(max_r > min_r)) return out;
  out.col0 = static_cast<int>(std::floor(min_c));
  out.row0 = static_cast<int>(std::floor(min_r));
  const int cols = static_cast<int>(std::ceil(max_c)) - out.col0;
  const int rows = static_cast<int>(std::ceil(max_r)) - out.row0;

  const Eigen::Vector2d centre(box.x + 0.5 * box.width, box.y + 0.5 * box.height);
  const Eigen::Vector2d centre_on_orbital = to_orbital.Apply(centre);
  out.scale = PixelSizeM(orbital_grid, centre_on_orbital) / PixelSizeM(ortho_grid, centre);

  // Low-pass in ortho pixels, nodata-aware (normalized convolution).
  cv::Mat value(ortho.image.size(), CV_32F, cv::Scalar(0.0f));
  ortho.image.copyTo(value, valid);
  cv::Mat weight;
  valid.convertTo(weight, CV_32F, 1.0 / 255.0);
  const double sigma = options.lowpass_sigma_orbital_px * out.scale;
  if (sigma > 0.3) {
    cv::GaussianBlur(value, value, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
    cv::GaussianBlur(weight, weight, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  }

  // Ortho pixel coordinates of each template pixel centre: exact on a lattice, bilinear between.
  const int step = options.lattice_step_px;
  const int lat_rows = rows / step + 2, lat_cols = cols / step + 2;
  cv::Mat lat_x(lat_rows, lat_cols, CV_64F), lat_y(lat_rows, lat_cols, CV_64F);
  const GridMapping to_ortho(orbital_grid, ortho_grid);
  for (int i = 0; i < lat_rows; ++i) {
    for (int j = 0; j < lat_cols; ++j) {
      const Eigen::Vector2d q =
          to_ortho.Apply({out.col0 + j * step + 0.5, out.row0 + i * step + 0.5});
      lat_x.at<double>(i, j) = q.x();
      lat_y.at<double>(i, j) = q.y();
    }
  }
  out.ortho_x.create(rows, cols, CV_32F);
  out.ortho_y.create(rows, cols, CV_32F);
  cv::Mat map_x(rows, cols, CV_32F), map_y(rows, cols, CV_32F);
  tbb::parallel_for(0, rows, [&](int r) {
    const int i = r / step;
    const double fr = static_cast<double>(r - i * step) / step;
    for (int c = 0; c < cols; ++c) {
      const int j = c / step;
      const double fc = static_cast<double>(c - j * step) / step;
      const auto bilinear = [&](const cv::Mat& m) {
        return (1 - fr) * ((1 - fc) * m.at<double>(i, j) + fc * m.at<double>(i, j + 1)) +
               fr * ((1 - fc) * m.at<double>(i + 1, j) + fc * m.at<double>(i + 1, j + 1));
      };
      const double x = bilinear(lat_x), y = bilinear(lat_y);
      out.ortho_x.at<float>(r, c) = static_cast<float>(x);
      out.ortho_y.at<float>(r, c) = static_cast<float>(y);
      // cv::remap puts pixel centres at integers.
      map_x.at<float>(r, c) = std::isfinite(x) ? static_cast<float>(x - 0.5) : -1e6f;
      map_y.at<float>(r, c) = std::isfinite(y) ? static_cast<float>(y - 0.5) : -1e6f;
    }
  });
  cv::Mat sampled_value, sampled_weight;
  cv::remap(value, sampled_value, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0.0);
  cv::remap(weight, sampled_weight, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0.0);
  // Pixels whose footprint strays outside the range or the valid data are dropped; the
  // nearest-neighbour validity keeps a template pixel that samples mostly one invalid pixel
  // out even when the blurred weight is high.
  cv::Mat nearest_valid;
  cv::remap(valid, nearest_valid, map_x, map_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
  out.image.create(rows, cols, CV_32F);
  out.mask.create(rows, cols, CV_8U);
  const float min_coverage = static_cast<float>(options.min_coverage);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const float w = sampled_weight.at<float>(r, c);
      const bool ok = w >= min_coverage && nearest_valid.at<uchar>(r, c) != 0;
      out.image.at<float>(r, c) = ok ? sampled_value.at<float>(r, c) / w : kNaNf;
      out.mask.at<uchar>(r, c) = ok ? 255 : 0;
      out.valid_pixels += ok ? 1 : 0;
    }
  }
  return out;
}

}  // namespace areomap
