#include "areomap/map/coordinate_system.h"

#include <cmath>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/map/projection.h"
#include "areomap/map/raster.h"
#include "test_support.h"

namespace areomap {
namespace {

TEST(CoordinateSystem, ConvertsBetweenGeographicTypesThroughMbf) {
  const CoordinateSystemContext context;
  const auto ocentric = CoordinateSystem::Parse("planetocentric", context);
  const auto ographic_west = CoordinateSystem::Parse("planetographic,west,360", context);
  const Eigen::Vector3d in(45.0, 10.0, 0.0);
  const Eigen::Vector3d out = ographic_west.FromMbf(ocentric.ToMbf(in));
  EXPECT_NEAR(out.x(), 45.338231953381, 1e-9);  // cs2cs IAU_2015:49902 -> 49901.
  EXPECT_NEAR(out.y(), 350.0, 1e-9);
  EXPECT_NEAR(out.z(), 0.0, 1e-6);
}

TEST(CoordinateSystem, IauCrsUsesLongitudeFirstAndMatchesGeographic) {
  const CoordinateSystemContext context;
  const auto iau = CoordinateSystem::Parse("IAU_2015:49902", context);
  const auto ocentric = CoordinateSystem::Parse("planetocentric", context);
  EXPECT_LT((iau.ToMbf({10.0, 45.0, 100.0}) - ocentric.ToMbf({45.0, 10.0, 100.0})).norm(), 1e-6);
}

TEST(CoordinateSystem, SiteFrameNeedsAnOriginAndPutsItAtZero) {
  CoordinateSystemContext context;
  EXPECT_NE(
      testing::ErrorMessageOf([&] { CoordinateSystem::Parse("site", context); }).find("--origin"),
      std::string::npos);
  context.origin = Geographic{RadFromDeg(-14.5), RadFromDeg(175.5), -1900.0};
  const auto site = CoordinateSystem::Parse("site", context);
  const auto ocentric = CoordinateSystem::Parse("planetocentric", context);
  EXPECT_LT(site.FromMbf(ocentric.ToMbf({-14.5, 175.5, -1900.0})).norm(), 1e-6);
}

TEST(CoordinateSystem, RejectsBadLinesAndNames) {
  const CoordinateSystemContext context;
  const auto ocentric = CoordinateSystem::Parse("planetocentric", context);
  EXPECT_NE(testing::ErrorMessageOf([&] {
              ocentric.ToMbf({91.0, 0.0, 0.0});
            }).find("latitude 91 is outside"),
            std::string::npos);
  EXPECT_THROW(ocentric.ToMbf({std::nan(""), 0.0, 0.0}), Error);
  EXPECT_NE(testing::ErrorMessageOf([&] {
              CoordinateSystem::Parse("planetocentric,sideways", context);
            }).find("unknown modifier 'sideways'"),
            std::string::npos);
  EXPECT_NE(testing::ErrorMessageOf([&] {
              CoordinateSystem::Parse("EPSG:4326", context);
            }).find("not on Mars"),
            std::string::npos);
}

TEST(PointLine, ExtraTokensAreAnErrorNamingTheCountNotIgnored) {
  EXPECT_EQ(ParsePointLine("1, 2\t3 # note"), Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_EQ(ParsePointLine("1 2"), Eigen::Vector3d(1.0, 2.0, 0.0));
  EXPECT_EQ(testing::ErrorMessageOf([] { ParsePointLine("1 2 3 4"); }),
            "expected 2 or 3 numbers, got 4");
  EXPECT_EQ(ParsePointLine("1 2 3", 3), Eigen::Vector3d(1.0, 2.0, 3.0));
  EXPECT_EQ(testing::ErrorMessageOf([] { ParsePointLine("1 2 3 4", 3); }),
            "expected 3 numbers, got 4");
  EXPECT_EQ(testing::ErrorMessageOf([] { ParsePointLine("1 2", 3); }), "expected 3 numbers, got 2");
  EXPECT_EQ(testing::ErrorMessageOf([] { ParsePointLine("1 2 3 x", 3); }), "'x' is not a number");
}

TEST(PointLine, BlankAndCommentLinesAreEmpty) {
  EXPECT_TRUE(PointLineIsEmpty(""));
  EXPECT_TRUE(PointLineIsEmpty(" \t,\r"));
  EXPECT_TRUE(PointLineIsEmpty("  # a comment 1 2 3"));
  EXPECT_FALSE(PointLineIsEmpty("1 # a comment"));
}

TEST(CoordinateSystem, PixelAndRasterSystemsFollowTheFilesGeoreference) {
  testing::TempDir dir;
  const MapProjection projection =
      MapProjection::Equirectangular(Body::MarsSphere(), 0.0, RadFromDeg(175.0));
  GeoRaster raster;
  raster.bands = {cv::Mat::zeros(10, 10, CV_32F)};
  raster.geotransform = GeoTransform::NorthUp(-5.0, 5.0, 1.0, 1.0);
  raster.crs_wkt = projection.Wkt();
  WriteGeoTiff(dir.path() / "r.tif", raster);
  const CoordinateSystemContext context;
  const auto pixel = CoordinateSystem::Parse("pixel:" + (dir.path() / "r.tif").string(), context);
  const auto map = CoordinateSystem::Parse("raster:" + (dir.path() / "r.tif").string(), context);
  const auto ocentric = CoordinateSystem::Parse("planetocentric", context);
  // The centre of the raster (pixel 5, 5) is the projection's origin: lat 0, lon 175.
  const Eigen::Vector3d centre = ocentric.FromMbf(pixel.ToMbf({5.0, 5.0, 0.0}));
  EXPECT_NEAR(centre.x(), 0.0, 1e-9);
  EXPECT_NEAR(centre.y(), 175.0, 1e-9);
  EXPECT_LT((map.FromMbf(pixel.ToMbf({0.5, 0.5, 0.0})) - Eigen::Vector3d(-4.5, 4.5, 0.0)).norm(),
            1e-6);
}

// CRS systems carry their datum's radii (what `coords` uses for the other side by default);
// the geographic and local systems have none of their own.
TEST(CoordinateSystem, DatumBodyIsTheCrsEllipsoid) {
  const CoordinateSystemContext context;
  const std::optional<Body> sphere = CoordinateSystem::Parse("IAU_2015:49910", context).DatumBody();
  ASSERT_TRUE(sphere.has_value());
  EXPECT_EQ(sphere->a, 3396190.0);
  EXPECT_EQ(sphere->b, 3396190.0);
  const std::optional<Body> ellipsoid =
      CoordinateSystem::Parse("IAU_2015:49902", context).DatumBody();
  ASSERT_TRUE(ellipsoid.has_value());
  EXPECT_EQ(ellipsoid->b, 3376200.0);
  EXPECT_FALSE(CoordinateSystem::Parse("planetocentric", context).DatumBody().has_value());
  EXPECT_FALSE(CoordinateSystem::Parse("mbf", context).DatumBody().has_value());
  EXPECT_TRUE(CoordinateSystem::Parse("planetocentric", context).UsesBody());
  EXPECT_FALSE(CoordinateSystem::Parse("mbf", context).UsesBody());
  EXPECT_FALSE(CoordinateSystem::Parse("IAU_2015:49910", context).UsesBody());
}

}  // namespace
// A conversion takes the CRS's datum for the geographic side unless a body is given, and keeps
// the point where it is in space either way (the same MBF point).
TEST(CoordinateConversion, TakesTheCrsDatumUnlessABodyIsGiven) {
  const CoordinateSystemContext context;  // IAU 2000 ellipsoid
  const CoordinateConversion on_datum =
      CoordinateConversion::Make("IAU_2015:49910", "planetocentric", context, false);
  ASSERT_TRUE(on_datum.datum_body.has_value());
  EXPECT_EQ(on_datum.datum_body->a, 3396190.0);
  EXPECT_EQ(on_datum.datum_body->b, 3396190.0);
  EXPECT_EQ(on_datum.datum_source, "IAU_2015:49910");
  const CoordinateConversion on_body =
      CoordinateConversion::Make("IAU_2015:49910", "planetocentric", context, true);
  EXPECT_FALSE(on_body.datum_body.has_value());
  const Eigen::Vector3d xy_h(1.0e5, 8.0e5, -1500.0);  // equirectangular x, y [m], h [m]
  const Eigen::Vector3d sphere = on_datum.Convert(xy_h);
  const Eigen::Vector3d ellipsoid = on_body.Convert(xy_h);
  // The same longitude; latitude and height differ by the two surfaces' separation.
  EXPECT_NEAR(sphere.y(), ellipsoid.y(), 1e-9);
  EXPECT_GT(std::abs(sphere.z() - ellipsoid.z()), 1.0);
  // A system without a datum on either side leaves the context's body.
  EXPECT_FALSE(
      CoordinateConversion::Make("mbf", "planetocentric", context, false).datum_body.has_value());
}

}  // namespace areomap
