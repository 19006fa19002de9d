// A raster's pyramid levels, level 0 included, as temporary uncompressed Float32 files, internal
// to the crater module (raster_levels.h): the raster is decoded once, and each level is then read
// without decoding it again.
//
// Level l is (width >> l) x (height >> l) px; its pixel is the mean of the 2^l x 2^l block of
// full-resolution pixels under it, NaN where any of them is nodata (as ReadDecimated), built
// level by level from 2 x 2 means, strips in parallel (TBB): levels 0 and 1 from the raster, each
// next level from the file below. Disk: DiskBytes, in the system's temporary folder; the files are
// unlinked as soon as they are created, so nothing is left behind, not even after a crash.
// Memory: one strip per thread.
#pragma once

#include <functional>
#include <limits>
#include <vector>

#include <opencv2/core.hpp>

namespace areomap::internal {

class PyramidLevelFiles {
 public:
  // Reads a window of the full-resolution raster as CV_32F, NaN = nodata; called from several
  // threads at once.
  using RasterReader = std::function<cv::Mat(const cv::Rect& rect)>;
  // Every level down to 1 px on the shorter side.
  static constexpr int kAllLevels = std::numeric_limits<int>::max();

  // Levels 0 .. levels - 1 of a raster of `size` read through `read` (fewer where a level would
  // be empty). Throws areomap::Error when a file cannot be made or written (no temporary folder,
  // a full disk), or as `read` does; nothing is left behind then either.
  PyramidLevelFiles(cv::Size size, int levels, const RasterReader& read);
  ~PyramidLevelFiles();
  PyramidLevelFiles(const PyramidLevelFiles&) = delete;
  PyramidLevelFiles& operator=(const PyramidLevelFiles&) = delete;

  // `rect` (inside the level) of `level` (0 .. levels - 1) as CV_32F. Safe from several threads
  // at once. Throws areomap::Error on a failed read. ReadInto writes into `*out` when it already
  // has that size and type (a reused buffer), else points it at a new matrix.
  cv::Mat Read(int level, const cv::Rect& rect) const;
  void ReadInto(int level, const cv::Rect& rect, cv::Mat* out) const;

  // The disk all levels of a raster of `size` take: 4/3 of it as Float32 at most [bytes].
  static double DiskBytes(cv::Size size) { return 4.0 / 3.0 * 4.0 * size.area(); }

 private:
  struct Level {
    int fd = -1;
    cv::Size size;
  };
  void WriteRows(const Level& level, int row0, const cv::Mat& rows) const;
  std::vector<Level> levels_;  // levels_[l] is level l
};

}  // namespace areomap::internal
