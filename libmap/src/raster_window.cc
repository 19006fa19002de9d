#include "areomap/map/raster_window.h"

#include <algorithm>
#include <cmath>

namespace areomap {
namespace {

// Rows of the band read at a time by ValidPixelWindow.
constexpr int kScanRows = 256;

bool IsValid(float value, ValidCells rule) {
  return rule == ValidCells::kFinite ? std::isfinite(value) : value > 0.0f;
}

}  // namespace

std::optional<PixelWindow> ValidPixelWindow(const RasterDataset& dataset, int band,
                                            ValidCells rule) {
  const RasterInfo& info = dataset.info();
  int col0 = info.width, col1 = -1, row0 = info.height, row1 = -1;
  cv::Mat strip;  // Reused: one strip's memory for the whole scan.
  for (int row = 0; row < info.height; row += kScanRows) {
    const int rows = std::min(kScanRows, info.height - row);
    dataset.ReadWindowFloatInto(band, PixelWindow{0, row, info.width, rows}, &strip);
    for (int r = 0; r < rows; ++r) {
      const float* v = strip.ptr<float>(r);
      for (int c = 0; c < info.width; ++c) {
        if (!IsValid(v[c], rule)) continue;
        col0 = std::min(col0, c);
        col1 = std::max(col1, c);
        row0 = std::min(row0, row + r);
        row1 = std::max(row1, row + r);
      }
    }
  }
  if (col1 < 0) return std::nullopt;
  return PixelWindow{col0, row0, col1 - col0 + 1, row1 - row0 + 1};
}

GeoTransform WindowTransform(const GeoTransform& transform, const PixelWindow& window) {
  GeoTransform out = transform;
  const Eigen::Vector2d origin = transform.PixelToMap(window.col0, window.row0);
  out.c[0] = origin.x();
  out.c[3] = origin.y();
  return out;
}

}  // namespace areomap
