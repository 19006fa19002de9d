// A raster's pyramid levels, level 0 included, as temporary uncompressed Float32 files, internal
// to the learned crater detector (learned_detector.cc): the raster is decoded once, and each level
// is then read without decoding it again (on a large compressed raster, beyond GDAL's block cache,
// the decoding took a third of the detection's time, once per level and once more for level 0).
//
// Level l is (width >> l) x (height >> l) px; its pixel is the mean of the 2^l x 2^l block of
// full-resolution pixels under it, NaN where any of them is nodata (as ReadDecimated), built
// level by level from 2 x 2 means, strips in parallel (TBB): levels 0 and 1 from the raster, each
// next level from the file below. Disk: about 4/3 of the raster as Float32, in the system's
// temporary folder; the files are unlinked as soon as they are created, so nothing is left behind,
// not even after a crash. Memory: one strip per thread.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "areomap/map/raster.h"

namespace areomap::internal {

class PyramidLevelFiles {
 public:
  // Levels 0 .. levels - 1 of band 1 of `dataset` (fewer where a level would be empty). Throws
  // areomap::Error when a file cannot be made or written (no temporary folder, a full disk);
  // nothing is left behind then either.
  PyramidLevelFiles(const RasterDataset& dataset, int levels);
  ~PyramidLevelFiles();
  PyramidLevelFiles(const PyramidLevelFiles&) = delete;
  PyramidLevelFiles& operator=(const PyramidLevelFiles&) = delete;

  // `rect` (inside the level) of `level` (0 .. levels - 1) as CV_32F. Safe from several threads
  // at once. Throws areomap::Error on a failed read. ReadInto writes into `*out` when it already
  // has that size and type (a reused buffer), else points it at a new matrix.
  cv::Mat Read(int level, const cv::Rect& rect) const;
  void ReadInto(int level, const cv::Rect& rect, cv::Mat* out) const;

 private:
  struct Level {
    int fd = -1;
    cv::Size size;
  };
  void WriteRows(const Level& level, int row0, const cv::Mat& rows) const;
  std::vector<Level> levels_;  // levels_[l] is level l
};

}  // namespace areomap::internal
