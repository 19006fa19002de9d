#include "areomap/map/crs.h"

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/map/projection.h"
#include "test_support.h"

namespace areomap {
namespace {

TEST(Crs, DescribesIauLatitudeTypesAndLongitudeDirections) {
  const CrsDescription ographic_west = Crs::FromUserInput("IAU_2015:49901").Describe();
  EXPECT_TRUE(ographic_west.is_mars);
  EXPECT_EQ(ographic_west.latitude_type, LatitudeType::kPlanetographic);
  EXPECT_EQ(ographic_west.longitude_direction, LongitudeDirection::kWest);
  EXPECT_EQ(ographic_west.authority, "IAU_2015:49901");

  const CrsDescription ocentric = Crs::FromUserInput("IAU_2015:49902").Describe();
  EXPECT_EQ(ocentric.latitude_type, LatitudeType::kPlanetocentric);
  EXPECT_EQ(ocentric.longitude_direction, LongitudeDirection::kEast);
  EXPECT_DOUBLE_EQ(ocentric.body.a, 3396190.0);
  EXPECT_NEAR(ocentric.body.b, 3376200.0, 1e-6);

  const CrsDescription equirectangular = Crs::FromUserInput("IAU_2015:49910").Describe();
  EXPECT_TRUE(equirectangular.is_projected);
  EXPECT_EQ(equirectangular.projection_method, "Equirectangular");
  EXPECT_TRUE(equirectangular.body.IsSphere());
}

TEST(Crs, EarthCrsIsRejectedWhereMarsIsRequired) {
  const Crs wgs84 = Crs::FromUserInput("EPSG:4326");
  EXPECT_FALSE(wgs84.Describe().is_mars);
  const std::string message = testing::ErrorMessageOf([&] { wgs84.RequireMars(); });
  EXPECT_NE(message.find("is not on Mars"), std::string::npos) << message;
  EXPECT_NE(message.find("6378137"), std::string::npos) << message;
}

TEST(Crs, UnknownNameIsAnErrorThatQuotesIt) {
  const std::string message = testing::ErrorMessageOf([] { Crs::FromUserInput("IAU_2015:12345"); });
  EXPECT_NE(message.find("unknown CRS 'IAU_2015:12345'"), std::string::npos) << message;
}

TEST(Crs, ProjectedTransformRoundTripsThroughMbf) {
  const MapProjection projection = MapProjection::Sinusoidal(Body::Mars2000(), RadFromDeg(141.5));
  const CrsTransform transform(Crs::FromWkt(projection.Wkt(), "test"));
  EXPECT_EQ(transform.description().latitude_type, LatitudeType::kPlanetocentric);
  const Geographic g{RadFromDeg(34.27), RadFromDeg(141.57), 120.0};
  const Eigen::Vector2d xy = projection.Forward(g);
  const auto p = transform.ToMbf({xy.x(), xy.y(), g.h});
  ASSERT_TRUE(p.has_value());
  EXPECT_LT((*p - MbfFromGeographic(Body::Mars2000(), g)).norm(), 1e-3);
  const auto back = transform.FromMbf(*p);
  ASSERT_TRUE(back.has_value());
  EXPECT_LT((back->head<2>() - xy).norm(), 1e-6);
  EXPECT_NEAR(back->z(), g.h, 1e-6);
  const auto planetocentric = transform.ToPlanetocentric(xy);
  ASSERT_TRUE(planetocentric.has_value());
  EXPECT_NEAR(planetocentric->lat, g.lat, 1e-12);
}

}  // namespace
}  // namespace areomap
