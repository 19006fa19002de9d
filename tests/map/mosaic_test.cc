#include "areomap/map/mosaic.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "areomap/map/crs.h"
#include "areomap/map/projection.h"
#include "test_support.h"

namespace areomap {
namespace {

double Pattern(int col, int row) { return std::sin(0.3 * col) + std::cos(0.2 * row); }

// An orthophoto of columns [col0, col0 + width) of a 0.1 m grid, 20 rows, showing the pattern
// plus `offset` at ground sample `resolution`.
Orthophoto Strip(int col0, int width, double offset, double resolution, int id) {
  Orthophoto o;
  o.grid.x_left = col0 * 0.1;
  o.grid.y_top = 2.0;
  o.grid.posting = 0.1;
  o.grid.width = width;
  o.grid.height = 20;
  o.image = cv::Mat(20, width, CV_32F);
  o.valid = cv::Mat(20, width, CV_8U, cv::Scalar(1));
  o.resolution = cv::Mat(20, width, CV_32F, cv::Scalar(resolution));
  o.source_id = cv::Mat(20, width, CV_32S, cv::Scalar(id));
  for (int r = 0; r < 20; ++r) {
    for (int c = 0; c < width; ++c) {
      o.image.at<float>(r, c) = static_cast<float>(Pattern(col0 + c, r) + offset);
    }
  }
  o.valid_cells = 20 * width;
  return o;
}

// Two strips overlapping on 20 columns, one 10 DN brighter: outside the overlap each keeps its
// value, across it the offset fades without a seam (a hard seam would jump 10 DN at once).
TEST(Orthomosaic, FeathersTheSeamBetweenSites) {
  const std::vector<Orthophoto> strips = {Strip(0, 60, 0.0, 0.01, 1), Strip(40, 60, 10.0, 0.01, 2)};
  const GridSpec grid = CommonGrid(strips);
  EXPECT_EQ(grid.width, 100);
  MosaicOptions options;
  options.feather_m = 1.0;
  const Orthophoto mosaic = MakeOrthomosaic(strips, grid, "", options);
  EXPECT_EQ(mosaic.valid_cells, 100 * 20);
  for (int r = 0; r < 20; ++r) {
    for (int c = 0; c < 100; ++c) {
      const double offset = mosaic.image.at<float>(r, c) - Pattern(c, r);
      if (c < 40) {
        EXPECT_NEAR(offset, 0.0, 1e-5);
      }
      if (c >= 60) {
        EXPECT_NEAR(offset, 10.0, 1e-5);
      }
      if (c > 0) {
        const double previous = mosaic.image.at<float>(r, c - 1) - Pattern(c - 1, r);
        EXPECT_LT(std::abs(offset - previous), 1.5) << "column " << c;
      }
    }
    EXPECT_NEAR(mosaic.image.at<float>(r, 50) - Pattern(50, r), 5.0, 1e-4);  // Symmetric.
    EXPECT_EQ(mosaic.source_id.at<int32_t>(r, 10), 1);
    EXPECT_EQ(mosaic.source_id.at<int32_t>(r, 90), 2);
  }
}

// Where sites overlap, the finer ground sample dominates the blend and the resolution map.
TEST(Orthomosaic, PrefersTheFinerGroundSample) {
  const std::vector<Orthophoto> strips = {Strip(0, 60, 0.0, 0.02, 1),
                                          Strip(40, 60, 10.0, 0.005, 2)};
  const Orthophoto mosaic = MakeOrthomosaic(strips, CommonGrid(strips), "", MosaicOptions{});
  // Column 55: both well inside their feather zone (0.5 m from A's edge, 1.5 m into B).
  EXPECT_GT(mosaic.image.at<float>(5, 55) - Pattern(55, 5), 9.0);
  EXPECT_FLOAT_EQ(mosaic.resolution.at<float>(5, 55), 0.005f);
  EXPECT_EQ(mosaic.source_id.at<int32_t>(5, 55), 2);
}

TEST(Orthomosaic, KeepsGapsInvalidAndWritesMaskAndCrs) {
  Orthophoto strip = Strip(0, 30, 0.0, 0.01, 4);
  strip.valid(cv::Rect(10, 0, 5, 20)).setTo(0);
  strip.image(cv::Rect(10, 0, 5, 20)).setTo(std::numeric_limits<float>::quiet_NaN());
  const std::string wkt =
      MapProjection::Equirectangular(Body::Mars2000(), 0.0, 0.0,
                                     EquirectangularRadius::kLocalAtCenterLatitude)
          .Wkt();
  const Orthophoto mosaic = MakeOrthomosaic({strip}, strip.grid, wkt, MosaicOptions{});
  EXPECT_EQ(mosaic.valid_cells, 25 * 20);
  EXPECT_TRUE(std::isnan(mosaic.image.at<float>(3, 12)));
  EXPECT_EQ(mosaic.source_id.at<int32_t>(3, 12), -1);
  testing::TempDir dir;
  WriteOrthophoto(dir.path() / "mosaic.tif", mosaic);
  const RasterDataset dataset = RasterDataset::Open(dir.path() / "mosaic.tif");
  EXPECT_TRUE(Crs::FromWkt(dataset.info().crs_wkt, "mosaic.tif").Describe().is_mars);
  const cv::Mat valid = dataset.ReadWindow(2, dataset.FullWindow());
  EXPECT_EQ(cv::countNonZero(valid), 25 * 20);
}

TEST(Orthomosaic, RejectsMisalignedOrthophotos) {
  std::vector<Orthophoto> strips = {Strip(0, 30, 0.0, 0.01, 1), Strip(20, 30, 0.0, 0.01, 2)};
  strips[1].grid.x_left += 0.05;  // Half a cell off.
  EXPECT_NE(testing::ErrorMessageOf([&] { CommonGrid(strips); }).find("not a window"),
            std::string::npos);
  EXPECT_NE(testing::ErrorMessageOf([&] { CommonGrid({}); }).find("no orthophotos"),
            std::string::npos);
}

}  // namespace
}  // namespace areomap
