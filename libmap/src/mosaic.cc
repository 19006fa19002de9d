#include "areomap/map/mosaic.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"

namespace areomap {

void MosaicOptions::Check() const {
  RequireOption(feather_m > 0.0 && std::isfinite(feather_m), "MosaicOptions.feather_m",
                "a positive width [m]");
}

GridSpec CommonGrid(const std::vector<Orthophoto>& orthophotos) {
  if (orthophotos.empty()) throw Error("mosaic: no orthophotos given");
  const GridSpec& first = orthophotos.front().grid;
  Eigen::Vector2d min(first.x_left, first.y_top - first.height * first.posting);
  Eigen::Vector2d max(first.x_left + first.width * first.posting, first.y_top);
  for (const Orthophoto& o : orthophotos) {
    min =
        min.cwiseMin(Eigen::Vector2d(o.grid.x_left, o.grid.y_top - o.grid.height * o.grid.posting));
    max =
        max.cwiseMax(Eigen::Vector2d(o.grid.x_left + o.grid.width * o.grid.posting, o.grid.y_top));
  }
  GridSpec grid = first;
  grid.x_left = min.x();
  grid.y_top = max.y();
  grid.width = static_cast<int>(std::lround((max.x() - min.x()) / first.posting));
  grid.height = static_cast<int>(std::lround((max.y() - min.y()) / first.posting));
  for (const Orthophoto& o : orthophotos) o.grid.OffsetIn(grid);  // Throws if misaligned.
  return grid;
}

Orthophoto MakeOrthomosaic(const std::vector<Orthophoto>& orthophotos, const GridSpec& grid,
                           const std::string& crs_wkt, const MosaicOptions& options,
                           const ProgressCallback& progress) {
  options.Check();
  grid.Check();
  if (orthophotos.empty()) throw Error("mosaic: no orthophotos given");
  constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
  cv::Mat weighted(grid.height, grid.width, CV_64F, cv::Scalar(0.0));
  cv::Mat weight_sum(grid.height, grid.width, CV_64F, cv::Scalar(0.0));
  cv::Mat best_weight(grid.height, grid.width, CV_64F, cv::Scalar(0.0));
  Orthophoto mosaic;
  mosaic.grid = grid;
  mosaic.crs_wkt = crs_wkt;
  mosaic.image = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  mosaic.resolution = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  mosaic.valid = cv::Mat(grid.height, grid.width, CV_8U, cv::Scalar(0));
  mosaic.source_id = cv::Mat(grid.height, grid.width, CV_32S, cv::Scalar(-1));
  // Cells some orthophoto covers.
  cv::Mat covered(grid.height, grid.width, CV_8U, cv::Scalar(0));
  for (const Orthophoto& o : orthophotos) {
    const Eigen::Vector2i offset = o.grid.OffsetIn(grid);
    cv::Mat window = covered(cv::Rect(offset.x(), offset.y(), o.grid.width, o.grid.height));
    cv::bitwise_or(window, o.valid, window);
  }
  const int margin = static_cast<int>(std::ceil(options.feather_m / grid.posting)) + 1;
  for (size_t k = 0; k < orthophotos.size(); ++k) {
    if (progress && !progress(static_cast<double>(k) / static_cast<double>(orthophotos.size()),
                              "mosaic: blending")) {
      throw Error("mosaic cancelled");
    }
    const Orthophoto& o = orthophotos[k];
    const Eigen::Vector2i offset = o.grid.OffsetIn(grid);
    // Distance [cells] to the nearest cell another orthophoto covers and this one does not (the
    // seams; the mosaic's outer edge is no seam), over the window grown by the feather width.
    const cv::Rect reach = cv::Rect(offset.x() - margin, offset.y() - margin,
                                    o.grid.width + 2 * margin, o.grid.height + 2 * margin) &
                           cv::Rect(0, 0, grid.width, grid.height);
    cv::Mat seam_free(reach.size(), CV_8U, cv::Scalar(1));
    seam_free.setTo(0, covered(reach));
    const cv::Rect own(offset.x() - reach.x, offset.y() - reach.y, o.grid.width, o.grid.height);
    cv::Mat own_part = seam_free(own);
    own_part.setTo(1, o.valid);
    cv::Mat distance;
    cv::distanceTransform(seam_free, distance, cv::DIST_L2, cv::DIST_MASK_PRECISE);
    tbb::parallel_for(0, o.grid.height, [&](int r) {
      for (int c = 0; c < o.grid.width; ++c) {
        if (!o.valid.at<uint8_t>(r, c)) continue;
        const double resolution = o.resolution.at<float>(r, c);
        const float value = o.image.at<float>(r, c);
        if (!(resolution > 0.0) || !std::isfinite(value)) continue;
        const double d = distance.at<float>(r + own.y, c + own.x) * grid.posting;
        const double w = std::min(1.0, d / options.feather_m) / (resolution * resolution);
        const int row = r + offset.y(), col = c + offset.x();
        weighted.at<double>(row, col) += w * value;
        weight_sum.at<double>(row, col) += w;
        if (w > best_weight.at<double>(row, col)) {
          best_weight.at<double>(row, col) = w;
          mosaic.resolution.at<float>(row, col) = static_cast<float>(resolution);
          mosaic.source_id.at<int32_t>(row, col) = o.source_id.at<int32_t>(r, c);
        }
      }
    });
  }
  for (int row = 0; row < grid.height; ++row) {
    for (int col = 0; col < grid.width; ++col) {
      const double w = weight_sum.at<double>(row, col);
      if (!(w > 0.0)) continue;
      mosaic.image.at<float>(row, col) = static_cast<float>(weighted.at<double>(row, col) / w);
      mosaic.valid.at<uint8_t>(row, col) = 1;
    }
  }
  mosaic.valid_cells = cv::countNonZero(mosaic.valid);
  if (progress && !progress(1.0, "mosaic: done")) throw Error("mosaic cancelled");
  return mosaic;
}

}  // namespace areomap
