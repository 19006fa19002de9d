// Band 1 of a raster and its pyramid of 2 x 2 means, read by the crater detectors from several
// threads at once. Internal to the crater module (crater_raster.cc, learned_detector.cc).
//
// Level l is (width >> l) x (height >> l) px, each pixel the mean of the 2^l x 2^l block under
// it, NaN where any of them is nodata (ReadDecimated). Reads come from temporary level files
// (level_files.h: the raster decoded once) where the caller asks for it and the raster is larger
// than GDAL's block cache holds, else from the raster through one GDAL handle per thread (a
// handle is not thread-safe). Reads throw areomap::Error on failure.
#pragma once

#include <optional>
#include <vector>

#include <tbb/enumerable_thread_specific.h>
#include <opencv2/core.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/crater/learned_detector.h"
#include "areomap/crater/learned_options.h"
#include "areomap/map/progress.h"
#include "areomap/map/raster.h"
#include "level_files.h"

namespace areomap::internal {

class RasterLevels {
 public:
  // With `decode_once`, a raster over 64 MB as Float32 is decoded into level files now, where the
  // temporary folder has room for them (if not, or if they cannot be written, reads go to the
  // raster). `dataset` must outlive this object.
  RasterLevels(const RasterDataset& dataset, bool decode_once);

  int width() const { return dataset_.info().width; }
  int height() const { return dataset_.info().height; }
  const RasterDataset& dataset() const { return dataset_; }

  // `rect` (inside the level) of `level` as CV_32F; ReadInto writes into `*out` when it already
  // has that size and type.
  cv::Mat Read(int level, const cv::Rect& rect) const;
  void ReadInto(int level, const cv::Rect& rect, cv::Mat* out) const;

 private:
  // Through this thread's own GDAL handle (a handle is not thread-safe).
  void ReadFromRaster(int level, const cv::Rect& rect, cv::Mat* out) const;

  const RasterDataset& dataset_;
  mutable tbb::enumerable_thread_specific<std::optional<RasterDataset>> readers_;
  std::optional<PyramidLevelFiles> files_;  // built from readers_: declared after them
};

// What the learned detector finds (learned_detector.cc): its craters and, where asked for, the
// combined detector's support (NetworkSupport, learned_detector.h; empty otherwise).
struct LearnedFinds {
  std::vector<CraterDetection> craters;
  NetworkSupport support;
};

// The learned detector on `levels` (DetectCratersLearned on a raster), or on an in-memory image.
LearnedFinds DetectCratersLearnedOn(const RasterLevels& levels,
                                    const CraterDetectorOptions& options,
                                    const LearnedDetectorOptions& learned, bool with_support,
                                    const ProgressCallback& progress);
LearnedFinds DetectCratersLearnedInImage(const cv::Mat& image, const CraterDetectorOptions& options,
                                         const LearnedDetectorOptions& learned, bool with_support,
                                         const ProgressCallback& progress);

}  // namespace areomap::internal
