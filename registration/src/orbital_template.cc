#include "areomap/registration/orbital_template.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "high_pass.h"

namespace areomap {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Mean pixel edge [m] of a grid at `pixel`.
double PixelSizeM(const PixelGrid& grid, const Eigen::Vector2d& pixel) {
  const Eigen::Matrix2d m = grid.EastNorthPerPixel(pixel);
  return 0.5 * (m.col(0).norm() + m.col(1).norm());
}

// Valid ortho pixels (OrthoImage::ValidMask) within `range_m` of the rover.
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
    // The pixel centre's offset from the rover [m] moves by en.col(0) per column.
    Eigen::Vector2d d = en * Eigen::Vector2d(0.5 - rover.x(), r + 0.5 - rover.y());
    for (int c = 0; c < valid.cols; ++c, d += en.col(0)) {
      if (d.squaredNorm() > range2) row[c] = 0;
    }
  });
  return valid;
}

// The orbital pixels the template covers: the footprint of the ortho's valid box on the orbital
// grid (its outline, densely: CRSs may rotate); std::nullopt where it has no area.
std::optional<cv::Rect> OrbitalFootprint(const cv::Rect& box, const GridMapping& to_orbital) {
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
  if (!(max_c > min_c) || !(max_r > min_r)) return std::nullopt;
  const int col0 = static_cast<int>(std::floor(min_c));
  const int row0 = static_cast<int>(std::floor(min_r));
  return cv::Rect(col0, row0, static_cast<int>(std::ceil(max_c)) - col0,
                  static_cast<int>(std::ceil(max_r)) - row0);
}

// The ortho low-passed in ortho pixels, nodata-aware (normalized convolution): the blur of value
// x validity and the blur of the validity, by a Gaussian of `sigma` ortho pixels (none <= 0.3).
// Both are 0 outside `box` grown by the kernel's reach (value and validity are 0 outside the
// valid box), so only that crop is blurred; the two on two cores.
struct NormalizedConvolution {
  cv::Mat value;   // CV_32F.
  cv::Mat weight;  // CV_32F, in [0, 1].
};

NormalizedConvolution LowPass(const OrthoImage& ortho, const cv::Mat& valid, const cv::Rect& box,
                              double sigma) {
  NormalizedConvolution out{cv::Mat(ortho.image.size(), CV_32F, cv::Scalar(0.0f)), cv::Mat()};
  ortho.image.copyTo(out.value, valid);
  valid.convertTo(out.weight, CV_32F, 1.0 / 255.0);
  if (sigma > 0.3) {
    const int reach = internal::GaussianReachPx(sigma);
    const cv::Rect grown =
        cv::Rect(box.x - reach, box.y - reach, box.width + 2 * reach, box.height + 2 * reach) &
        cv::Rect(0, 0, valid.cols, valid.rows);
    const auto blur = [&](cv::Mat& image) {
      cv::Mat crop = image(grown);
      cv::GaussianBlur(crop, crop, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
    };
    tbb::parallel_invoke([&] { blur(out.value); }, [&] { blur(out.weight); });
  }
  return out;
}

// cv::remap's maps from template pixels to ortho pixels (pixel centres at integers; far off the
// image where the CRSs cannot map).
struct RemapMaps {
  cv::Mat x;  // CV_32F.
  cv::Mat y;
};

// Ortho pixel coordinates of each template pixel centre: exact on a lattice every `step` pixels,
// bilinear between. Sets t.ortho_x and t.ortho_y (GDAL convention) of a template of `size`.
RemapMaps OrthoCoordinates(const PixelGrid& orbital_grid, const PixelGrid& ortho_grid, int step,
                           cv::Size size, OrbitalTemplate& t) {
  const int rows = size.height, cols = size.width;
  const int lat_rows = rows / step + 2, lat_cols = cols / step + 2;
  cv::Mat lat_x(lat_rows, lat_cols, CV_64F), lat_y(lat_rows, lat_cols, CV_64F);
  const GridMapping to_ortho(orbital_grid, ortho_grid);
  for (int i = 0; i < lat_rows; ++i) {
    for (int j = 0; j < lat_cols; ++j) {
      const Eigen::Vector2d q = to_ortho.Apply({t.col0 + j * step + 0.5, t.row0 + i * step + 0.5});
      lat_x.at<double>(i, j) = q.x();
      lat_y.at<double>(i, j) = q.y();
    }
  }
  t.ortho_x.create(rows, cols, CV_32F);
  t.ortho_y.create(rows, cols, CV_32F);
  RemapMaps maps{cv::Mat(rows, cols, CV_32F), cv::Mat(rows, cols, CV_32F)};
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
      t.ortho_x.at<float>(r, c) = static_cast<float>(x);
      t.ortho_y.at<float>(r, c) = static_cast<float>(y);
      // cv::remap puts pixel centres at integers.
      maps.x.at<float>(r, c) = std::isfinite(x) ? static_cast<float>(x - 0.5) : -1e6f;
      maps.y.at<float>(r, c) = std::isfinite(y) ? static_cast<float>(y - 0.5) : -1e6f;
    }
  });
  return maps;
}

// Samples the low-passed ortho at the maps: t.image, t.mask and t.valid_pixels. Pixels whose
// footprint strays outside the range or the valid data are dropped; the nearest-neighbour
// validity keeps a template pixel that samples mostly one invalid pixel out even when the
// blurred weight is high.
void SampleTemplate(const NormalizedConvolution& lowpassed, const cv::Mat& valid,
                    const RemapMaps& maps, double min_coverage_fraction, OrbitalTemplate& t) {
  const int rows = maps.x.rows, cols = maps.x.cols;
  cv::Mat sampled_value, sampled_weight, nearest_valid;
  tbb::parallel_invoke(
      [&] {
        cv::remap(lowpassed.value, sampled_value, maps.x, maps.y, cv::INTER_LINEAR,
                  cv::BORDER_CONSTANT, 0.0);
      },
      [&] {
        cv::remap(lowpassed.weight, sampled_weight, maps.x, maps.y, cv::INTER_LINEAR,
                  cv::BORDER_CONSTANT, 0.0);
      },
      [&] {
        cv::remap(valid, nearest_valid, maps.x, maps.y, cv::INTER_NEAREST, cv::BORDER_CONSTANT, 0);
      });
  t.image.create(rows, cols, CV_32F);
  t.mask.create(rows, cols, CV_8U);
  const float min_coverage = static_cast<float>(min_coverage_fraction);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const float w = sampled_weight.at<float>(r, c);
      const bool ok = w >= min_coverage && nearest_valid.at<uchar>(r, c) != 0;
      t.image.at<float>(r, c) = ok ? sampled_value.at<float>(r, c) / w : kNaNf;
      t.mask.at<uchar>(r, c) = ok ? 255 : 0;
      t.valid_pixels += ok ? 1 : 0;
    }
  }
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
  const cv::Rect box = cv::boundingRect(valid);
  if (box.empty()) return out;
  const GridMapping to_orbital(ortho_grid, orbital_grid);
  const std::optional<cv::Rect> footprint = OrbitalFootprint(box, to_orbital);
  if (!footprint) return out;
  out.col0 = footprint->x;
  out.row0 = footprint->y;

  const Eigen::Vector2d centre(box.x + 0.5 * box.width, box.y + 0.5 * box.height);
  const Eigen::Vector2d centre_on_orbital = to_orbital.Apply(centre);
  out.scale = PixelSizeM(orbital_grid, centre_on_orbital) / PixelSizeM(ortho_grid, centre);

  const NormalizedConvolution lowpassed =
      LowPass(ortho, valid, box, options.lowpass_sigma_orbital_px * out.scale);
  const RemapMaps maps =
      OrthoCoordinates(orbital_grid, ortho_grid, options.lattice_step_px, footprint->size(), out);
  SampleTemplate(lowpassed, valid, maps, options.min_coverage, out);
  return out;
}

}  // namespace areomap
