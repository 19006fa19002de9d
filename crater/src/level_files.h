// The pyramid levels above 0 of a raster as temporary uncompressed Float32 files, internal to the
// learned crater detector (learned_detector.cc): each level is read without decoding the raster
// again, which on a large compressed raster (beyond GDAL's block cache) took a third of the
// detection's time, once per level.
//
// Level l is (width >> l) x (height >> l) px; its pixel is the mean of the 2^l x 2^l block of
// full-resolution pixels under it, NaN where any of them is nodata (as ReadDecimated), built
// level by level from 2 x 2 means in one strip pass: level 1 from the raster, each next level from
// the file below. Disk: about a third of the raster as Float32, in the system's temporary folder;
// the files are unlinked as soon as they are created, so nothing is left behind, not even after a
// crash. Memory: one strip.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "areomap/map/raster.h"

namespace areomap::internal {

class PyramidLevelFiles {
 public:
  // Levels 1 .. levels - 1 of band 1 of `dataset`. Throws areomap::Error when a file cannot be
  // made or written (no temporary folder, a full disk); nothing is left behind then either.
  PyramidLevelFiles(const RasterDataset& dataset, int levels);
  ~PyramidLevelFiles();
  PyramidLevelFiles(const PyramidLevelFiles&) = delete;
  PyramidLevelFiles& operator=(const PyramidLevelFiles&) = delete;

  // `rect` (inside the level) of `level` (1 .. levels - 1) as CV_32F. Safe from several threads
  // at once. Throws areomap::Error on a failed read.
  cv::Mat Read(int level, const cv::Rect& rect) const;

 private:
  struct Level {
    int fd = -1;
    cv::Size size;
  };
  void WriteRows(const Level& level, int row0, const cv::Mat& rows) const;
  std::vector<Level> levels_;  // levels_[l - 1] is level l
};

}  // namespace areomap::internal
