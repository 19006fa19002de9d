// Rock extraction on the real K10 pair (../shared/data/k10: three landscaping rocks in a row on
// pavement, 1-5 m ahead of the rover, buildings and cars beyond). Full-size dense stereo, then
// ExtractRocks within 8 m. The rocks' image regions were read off left4.png (docs/rocks.md).
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "areomap/landmarks/rock_extraction.h"
#include "areomap/landmarks/rock_output.h"
#include "areomap/map/camera_models.h"
#include "areomap/map/dense_stereo.h"
#include "areomap/map/image_io.h"
#include "test_support.h"

namespace areomap {
namespace {

PointCloud K10Cloud() {
  const auto dir = testing::SharedDataDir() / "k10";
  DenseStereoOptions options;
  options.min_range_m = 0.8;  // The near rock's front is 1.0 m from the camera.
  options.max_range_m = 8.0;
  return RunDenseStereo(ReadImage(dir / "left4.png"), ReadImage(dir / "right4.png"),
                        ReadCameraFile(dir / "black_left.tsai"),
                        ReadCameraFile(dir / "black_right.tsai"), options)
      .cloud;
}

TEST(RockExtractionK10, FindsAndModelsTheThreeRocks) {
  SKIP_WITHOUT_SHARED_DATA();
  const PointCloud cloud = K10Cloud();
  ASSERT_GT(cloud.points.size(), 100000u);
  RockExtractionOptions options;
  options.max_peak_range_m = 8.0;
  const std::vector<ExtractedRock> rocks = ExtractRocks(cloud, options);
  // Left-image boxes (column, row, width, height) around each rock's top; the third rock shows
  // only its top above the second.
  const cv::Rect boxes[] = {{430, 315, 285, 285}, {535, 160, 130, 125}, {570, 120, 85, 40}};
  for (const cv::Rect& box : boxes) {
    SCOPED_TRACE(::testing::Message() << "rock box at " << box.x << "," << box.y);
    const ExtractedRock* found = nullptr;
    int peaks_in_box = 0;
    for (const ExtractedRock& r : rocks) {
      const StereoPoint& peak = cloud.points[static_cast<size_t>(r.peak_index)];
      if (box.contains(cv::Point(static_cast<int>(std::lround(peak.left_x)),
                                 static_cast<int>(std::lround(peak.left_y))))) {
        found = &r;
        ++peaks_in_box;
      }
    }
    // One rock, one peak: the other local maxima on its surface are merged into it.
    ASSERT_EQ(peaks_in_box, 1);
    EXPECT_TRUE(found->modeled());
    // About knee high (the camera, 0.75 m above the pavement, looks down on each top).
    EXPECT_GT(found->height_m, 0.2);
    EXPECT_LT(found->height_m, 0.6);
    EXPECT_GT(found->surface_indices.size(), 500u);
  }
}

}  // namespace
}  // namespace areomap
