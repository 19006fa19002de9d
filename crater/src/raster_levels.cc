#include "raster_levels.h"

#include <filesystem>
#include <system_error>

#include "areomap/map/error.h"

namespace areomap::internal {
namespace {

// Rasters over this many bytes as Float32 (4096 x 4096 px) are decoded into level files: half of
// areomap's GDAL block cache (gdal_util.h); a smaller raster is decoded once into the cache.
constexpr double kLevelFilesFromBytes = 64.0 * (1 << 20);

// Whether the temporary folder has room for the level files of a raster of `size` and a quarter
// more, so that a detection does not fill the disk for others.
bool RoomForLevelFiles(cv::Size size) {
  std::error_code error;
  const auto space = std::filesystem::space(std::filesystem::temp_directory_path(error), error);
  return !error && static_cast<double>(space.available) > 1.25 * PyramidLevelFiles::DiskBytes(size);
}

}  // namespace

RasterLevels::RasterLevels(const RasterDataset& dataset, bool decode_once) : dataset_(dataset) {
  const cv::Size size(width(), height());
  if (!decode_once || 4.0 * size.area() <= kLevelFilesFromBytes || !RoomForLevelFiles(size)) return;
  try {
    files_.emplace(size, PyramidLevelFiles::kAllLevels, [this](const cv::Rect& rect) {
      cv::Mat out;
      ReadFromRaster(0, rect, &out);
      return out;
    });
  } catch (const Error&) {
    files_.reset();  // a full disk or no temporary folder: read the raster instead
  }
}

cv::Mat RasterLevels::Read(int level, const cv::Rect& rect) const {
  cv::Mat out;
  ReadInto(level, rect, &out);
  return out;
}

void RasterLevels::ReadInto(int level, const cv::Rect& rect, cv::Mat* out) const {
  if (files_) {
    files_->ReadInto(level, rect, out);
  } else {
    ReadFromRaster(level, rect, out);
  }
}

void RasterLevels::ReadFromRaster(int level, const cv::Rect& rect, cv::Mat* out) const {
  std::optional<RasterDataset>& reader = readers_.local();
  if (!reader) reader = dataset_.Reopen();
  if (level == 0) {
    reader->ReadWindowFloatInto(1, {rect.x, rect.y, rect.width, rect.height}, out);
    return;
  }
  const int f = 1 << level;
  *out = ReadDecimated(*reader, {rect.x * f, rect.y * f, rect.width * f, rect.height * f}, f);
}

}  // namespace areomap::internal
