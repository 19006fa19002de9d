#include "raster_levels.h"

#include <algorithm>
#include <filesystem>
#include <system_error>

#include "areomap/map/error.h"

namespace areomap::internal {
namespace {

// Rasters over this many bytes as Float32 (4096 x 4096 px) are decoded into level files: half of
// areomap's GDAL block cache (gdal_util.h); a smaller raster is decoded once into the cache.
constexpr double kLevelFilesFromBytes = 64.0 * (1 << 20);

// Every level down to 1 px on the shorter side.
int AllLevels(int width, int height) {
  int levels = 1;
  while (std::min(width >> levels, height >> levels) >= 1) ++levels;
  return levels;
}

// Whether the temporary folder has room for the level files of a raster of `bytes` as Float32
// (4/3 of it) and a quarter more, so that a detection does not fill the disk for others.
bool RoomForLevelFiles(double bytes) {
  std::error_code error;
  const auto space = std::filesystem::space(std::filesystem::temp_directory_path(error), error);
  return !error && static_cast<double>(space.available) > 1.25 * (4.0 / 3.0) * bytes;
}

}  // namespace

RasterLevels::RasterLevels(const RasterDataset& dataset, bool decode_once) : dataset_(dataset) {
  const RasterInfo& info = dataset.info();
  const double bytes = 4.0 * info.width * info.height;
  if (!decode_once || bytes <= kLevelFilesFromBytes || !RoomForLevelFiles(bytes)) return;
  try {
    files_.emplace(dataset, AllLevels(info.width, info.height));
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
    return;
  }
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
