// The learned detector's temporary pyramid level files (crater/src/level_files.h) against
// ReadDecimated, the reads they replace.
#include "level_files.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <mutex>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/map/raster.h"
#include "small_tiled_raster.h"

namespace areomap {
namespace {

// Every level of an odd-sized tiled raster with nodata blocks, level 0 included: the same means as
// ReadDecimated (to float rounding), NaN exactly where a block holds nodata, any window, and no
// file to be seen in the temporary folder.
TEST(PyramidLevelFiles, HoldTheMeansThatReadDecimatedReads) {
  const auto dir = std::filesystem::temp_directory_path() / "areomap_level_files_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  cv::Mat image(613, 1031, CV_32F);
  cv::randu(image, 0.0, 1000.0);
  image(cv::Rect(100, 40, 7, 5)).setTo(std::numeric_limits<float>::quiet_NaN());
  const RasterDataset dataset = testing::WriteSmallTiledRaster(dir / "image.tif", image);
  // The strips are read from several threads; one GDAL handle is not thread-safe.
  std::mutex reading;
  const internal::PyramidLevelFiles files(image.size(), 5, [&](const cv::Rect& rect) {
    const std::lock_guard<std::mutex> lock(reading);
    return dataset.ReadWindowFloat(1, {rect.x, rect.y, rect.width, rect.height});
  });
  for (int level = 0; level < 5; ++level) {
    const int f = 1 << level;
    const cv::Size size(image.cols >> level, image.rows >> level);
    const cv::Mat expected = ReadDecimated(dataset, {0, 0, size.width * f, size.height * f}, f);
    const cv::Mat got = files.Read(level, cv::Rect(0, 0, size.width, size.height));
    ASSERT_EQ(got.size(), size) << level;
    int nan = 0;
    for (int r = 0; r < size.height; ++r) {
      for (int c = 0; c < size.width; ++c) {
        const float e = expected.at<float>(r, c), g = got.at<float>(r, c);
        ASSERT_EQ(std::isnan(e), std::isnan(g)) << level << " " << r << " " << c;
        if (std::isnan(e)) {
          ++nan;
        } else {
          ASSERT_NEAR(g, e, 1e-3) << level << " " << r << " " << c;
        }
      }
    }
    EXPECT_GT(nan, 0) << level;
    const cv::Rect window(size.width / 3, size.height / 4, size.width / 2, size.height / 3);
    EXPECT_EQ(cv::norm(files.Read(level, window), got(window), cv::NORM_INF), 0.0) << level;
  }
  EXPECT_THROW(files.Read(5, cv::Rect(0, 0, 1, 1)), Error);
  EXPECT_THROW(files.Read(-1, cv::Rect(0, 0, 1, 1)), Error);
  EXPECT_THROW(files.Read(1, cv::Rect(0, 0, image.cols, 1)), Error);
  // The files are unlinked as soon as they are made: none is there while they are in use.
  for (const auto& entry :
       std::filesystem::directory_iterator(std::filesystem::temp_directory_path())) {
    EXPECT_NE(entry.path().filename().string().rfind("areomap-crater-level-", 0), 0u)
        << entry.path();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace areomap
