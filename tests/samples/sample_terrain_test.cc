#include "areomap/samples/sample_terrain.h"

#include <gtest/gtest.h>

#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/raster_description.h"
#include "test_support.h"

namespace areomap {
namespace {

TEST(SampleTerrain, CraterIsCentredWithTheRequestedDepth) {
  SampleTerrainOptions options;
  options.roughness_m = 0.0;
  const GeoRaster dtm = MakeSampleTerrain(options);
  const cv::Mat& z = dtm.bands.front();
  double min_z = 0.0, max_z = 0.0;
  cv::Point min_at, max_at;
  cv::minMaxLoc(z, &min_z, &max_z, &min_at, &max_at);
  // Floor at the tile centre (pixels 127/128 straddle it), rim crest 3 m above the plain.
  EXPECT_NEAR(min_at.x, 127.5, 0.5);
  EXPECT_NEAR(min_at.y, 127.5, 0.5);
  EXPECT_NEAR(max_z - min_z, options.crater_depth_m, 0.05);
  EXPECT_NEAR(max_z - options.base_elevation_m, options.rim_height_m, 0.05);
}

TEST(SampleTerrain, IsGeoreferencedAtTheRequestedPlaceOnMars) {
  testing::TempDir dir;
  const SampleTerrainOptions options;
  WriteGeoTiff(dir.path() / "dtm.tif", MakeSampleTerrain(options));
  const RasterDescription d = DescribeRaster(dir.path() / "dtm.tif");
  ASSERT_TRUE(d.crs.has_value());
  EXPECT_TRUE(d.crs->is_mars);
  const CornerCoordinate& centre = d.corners.back();
  ASSERT_EQ(centre.name, "center");
  EXPECT_NEAR(DegFromRad(centre.planetocentric->lat), options.center_lat_deg, 1e-9);
  EXPECT_NEAR(DegFromRad(centre.planetocentric->lon), options.center_lon_deg, 1e-9);
}

TEST(SampleTerrain, SameSeedSameBytesOtherSeedOtherRelief) {
  SampleTerrainOptions options;
  const cv::Mat a = MakeSampleTerrain(options).bands[0];
  const cv::Mat b = MakeSampleTerrain(options).bands[0];
  options.seed = 2;
  const cv::Mat c = MakeSampleTerrain(options).bands[0];
  EXPECT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0);
  EXPECT_GT(cv::norm(a, c, cv::NORM_INF), 0.1);
}

TEST(SampleTerrain, InvalidOptionsNameTheField) {
  SampleTerrainOptions options;
  options.posting_m = -1.0;
  try {
    options.Check();
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("SampleTerrainOptions.posting_m"), std::string::npos);
  }
}

}  // namespace
}  // namespace areomap
