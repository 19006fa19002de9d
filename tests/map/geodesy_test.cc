#include "areomap/map/geodesy.h"

#include <random>

#include <gtest/gtest.h>

#include "proj_oracle.h"

namespace areomap {
namespace {

using testing::RunProjTool;

constexpr int kPoints = 1000;
constexpr double kDegTolerance = 1e-9;
constexpr double kMetreTolerance = 1e-3;

// Random points over the whole planet (latitude uniform on the sphere), heights -8..+21 km.
std::vector<Geographic> RandomPoints(uint32_t seed, int n = kPoints) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> lon(-std::numbers::pi, std::numbers::pi);
  std::uniform_real_distribution<double> h(-8000.0, 21000.0);
  std::vector<Geographic> out;
  for (int i = 0; i < n; ++i) out.push_back({std::asin(u(rng)), lon(rng), h(rng)});
  return out;
}

TEST(Geodesy, LatitudeConversionsAreExactAtPolesAndIdentityOnSphere) {
  const Body mars = Body::Mars2000();
  EXPECT_DOUBLE_EQ(PlanetographicFromPlanetocentric(mars, std::numbers::pi / 2),
                   std::numbers::pi / 2);
  EXPECT_DOUBLE_EQ(PlanetographicFromPlanetocentric(mars, 0.0), 0.0);
  EXPECT_DOUBLE_EQ(PlanetographicFromPlanetocentric(Body::MarsSphere(), 0.7), 0.7);
  // Planetographic latitude is larger in magnitude than planetocentric on an oblate body.
  EXPECT_GT(PlanetographicFromPlanetocentric(mars, 0.7), 0.7);
  EXPECT_NEAR(PlanetocentricFromPlanetographic(mars, PlanetographicFromPlanetocentric(mars, 0.7)),
              0.7, 1e-15);
}

TEST(Geodesy, WrapLongitudeCoversBothDomains) {
  const double pi = std::numbers::pi;
  EXPECT_NEAR(WrapLongitude(-pi / 2, LongitudeDomain::kZeroTo360), 1.5 * pi, 1e-15);
  EXPECT_NEAR(WrapLongitude(1.5 * pi, LongitudeDomain::kPlusMinus180), -pi / 2, 1e-15);
  EXPECT_NEAR(WrapLongitude(pi, LongitudeDomain::kPlusMinus180), -pi, 1e-15);
  EXPECT_NEAR(WrapLongitude(4 * pi + 0.1, LongitudeDomain::kZeroTo360), 0.1, 1e-12);
  EXPECT_GE(WrapLongitude(-1e-18, LongitudeDomain::kZeroTo360), 0.0);
}

TEST(Geodesy, PlanetocentricToPlanetographicWestAgreesWithProj) {
  const Body mars = Body::Mars2000();
  const auto points = RandomPoints(1);
  std::vector<Eigen::Vector3d> input;
  for (const auto& g : points) input.push_back({DegFromRad(g.lat), DegFromRad(g.lon), 0.0});
  // IAU_2015:49902 is planetocentric east, 49901 planetographic west; both lat first.
  const auto expected = RunProjTool("cs2cs -f %.15f IAU_2015:49902 IAU_2015:49901", input);
  const GeographicConvention ocentric_east;
  const GeographicConvention ographic_west{LatitudeType::kPlanetographic, LongitudeDirection::kWest,
                                           LongitudeDomain::kPlusMinus180};
  ASSERT_EQ(expected.size(), points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Geographic got = ConvertGeographic(mars, points[i], ocentric_east, ographic_west);
    EXPECT_NEAR(DegFromRad(got.lat), expected[i].x(), kDegTolerance) << i;
    const double dlon = DegFromRad(
        WrapLongitude(got.lon - RadFromDeg(expected[i].y()), LongitudeDomain::kPlusMinus180));
    EXPECT_NEAR(dlon, 0.0, kDegTolerance) << i;
  }
}

TEST(Geodesy, MbfAgreesWithProjForBothLatitudeTypes) {
  const Body mars = Body::Mars2000();
  const auto points = RandomPoints(2);
  std::vector<Eigen::Vector3d> input;
  for (const auto& g : points) input.push_back({DegFromRad(g.lon), DegFromRad(g.lat), g.h});
  const std::string ellipsoid = " +a=3396190 +b=3376200";
  const auto ographic = RunProjTool("cct -d 9 +proj=pipeline +step +proj=cart" + ellipsoid, input);
  const auto ocentric = RunProjTool(
      "cct -d 9 +proj=pipeline +step +inv +proj=geoc" + ellipsoid + " +step +proj=cart" + ellipsoid,
      input);
  const GeographicConvention graphic{LatitudeType::kPlanetographic};
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_LT((MbfFromGeographic(mars, points[i], graphic) - ographic[i]).norm(), kMetreTolerance);
    EXPECT_LT((MbfFromGeographic(mars, points[i]) - ocentric[i]).norm(), kMetreTolerance);
  }
}

TEST(Geodesy, MbfRoundTripsToAMicrometre) {
  for (const Body& body : {Body::Mars2000(), Body::MarsSphere(), Body::MolaSphere()}) {
    for (const GeographicConvention& convention :
         {GeographicConvention{},
          GeographicConvention{LatitudeType::kPlanetographic, LongitudeDirection::kWest,
                               LongitudeDomain::kZeroTo360}}) {
      for (const Geographic& g : RandomPoints(3)) {
        const Geographic in = ConvertGeographic(body, g, {}, convention);
        const Eigen::Vector3d p = MbfFromGeographic(body, in, convention);
        const Geographic back = GeographicFromMbf(body, p, convention);
        EXPECT_LT((MbfFromGeographic(body, back, convention) - p).norm(), 1e-6);
        EXPECT_NEAR(back.h, in.h, 1e-6);
      }
    }
  }
}

TEST(Geodesy, SphericalCoordinatesRoundTrip) {
  const Eigen::Vector3d p(1234567.0, -2345678.0, 1500000.0);
  const Spherical s = SphericalFromMbf(p);
  EXPECT_NEAR(s.radius, p.norm(), 1e-9);
  EXPECT_LT((MbfFromSpherical(s) - p).norm(), 1e-6);
}

TEST(Geodesy, EnuAgreesWithProjTopocentric) {
  const Body mars = Body::Mars2000();
  const Geographic origin{RadFromDeg(-14.5692), RadFromDeg(175.4729), -1900.0};
  const Geographic origin_graphic =
      ConvertGeographic(mars, origin, {}, {LatitudeType::kPlanetographic});
  const Rigid3d enu_from_mbf = EnuFromMbf(mars, origin);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> offset(-0.02, 0.02);  // ~1 km around the origin.
  std::uniform_real_distribution<double> height(-2500.0, -1500.0);
  std::vector<Geographic> points;
  std::vector<Eigen::Vector3d> input;
  for (int i = 0; i < kPoints; ++i) {
    points.push_back(
        {origin_graphic.lat + offset(rng), origin_graphic.lon + offset(rng), height(rng)});
    input.push_back(
        {DegFromRad(points.back().lon), DegFromRad(points.back().lat), points.back().h});
  }
  char origin_args[256];
  std::snprintf(origin_args, sizeof(origin_args), " +lat_0=%.15f +lon_0=%.15f +h_0=%.9f",
                DegFromRad(origin_graphic.lat), DegFromRad(origin_graphic.lon), origin.h);
  const std::string ellipsoid = " +a=3396190 +b=3376200";
  const auto expected = RunProjTool("cct -d 9 +proj=pipeline +step +proj=cart" + ellipsoid +
                                        " +step +proj=topocentric" + ellipsoid + origin_args,
                                    input);
  const GeographicConvention graphic{LatitudeType::kPlanetographic};
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d enu = enu_from_mbf * MbfFromGeographic(mars, points[i], graphic);
    EXPECT_LT((enu - expected[i]).norm(), kMetreTolerance) << i;
  }
}

TEST(Geodesy, SiteFrameIsNorthEastDown) {
  const Body mars = Body::Mars2000();
  const Geographic origin{RadFromDeg(-1.95), RadFromDeg(354.47), -1440.0};
  const Rigid3d site_from_mbf = SiteFromMbf(mars, origin);
  const Rigid3d enu_from_mbf = EnuFromMbf(mars, origin);
  const Eigen::Vector3d p = MbfFromGeographic(mars, origin) + Eigen::Vector3d(10, -20, 30);
  const Eigen::Vector3d enu = enu_from_mbf * p;
  const Eigen::Vector3d site = site_from_mbf * p;
  EXPECT_NEAR(site.x(), enu.y(), 1e-9);   // North.
  EXPECT_NEAR(site.y(), enu.x(), 1e-9);   // East.
  EXPECT_NEAR(site.z(), -enu.z(), 1e-9);  // Down.
  // The origin maps to zero and a point straight above it to negative z.
  EXPECT_LT((site_from_mbf * MbfFromGeographic(mars, origin)).norm(), 1e-6);
  Geographic above = origin;
  above.h += 5.0;
  EXPECT_NEAR((site_from_mbf * MbfFromGeographic(mars, above)).z(), -5.0, 1e-6);
  // Round trip through the inverse.
  EXPECT_LT((site_from_mbf.Inverse() * site - p).norm(), 1e-6);
}

TEST(Rigid3d, ComposesAndInverts) {
  const Rigid3d b_from_a(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                         Eigen::Vector3d(1, 2, 3));
  const Rigid3d c_from_b(Eigen::Quaterniond(Eigen::AngleAxisd(-1.1, Eigen::Vector3d::UnitX())),
                         Eigen::Vector3d(-4, 0, 2));
  const Eigen::Vector3d p_in_a(0.5, -0.25, 2.0);
  EXPECT_LT(((c_from_b * b_from_a) * p_in_a - c_from_b * (b_from_a * p_in_a)).norm(), 1e-12);
  EXPECT_LT((b_from_a.Inverse() * (b_from_a * p_in_a) - p_in_a).norm(), 1e-12);
}

}  // namespace
}  // namespace areomap

namespace areomap {
namespace {

TEST(Geodesy, RadialLinePointHasTheRequestedSphericalLatitudeAndHeight) {
  const Body mars = Body::Mars2000();
  const double lat = RadFromDeg(-14.5692), lon = RadFromDeg(175.4729);
  const Eigen::Vector3d p = MbfOnRadialLine(mars, lat, lon, -1900.0);
  const Spherical s = SphericalFromMbf(p);
  EXPECT_NEAR(s.lat, lat, 1e-14);
  EXPECT_NEAR(s.lon, lon, 1e-14);
  EXPECT_NEAR(GeographicFromMbf(mars, p).h, -1900.0, 1e-6);
  // The foot-point convention puts the same (lat, lon, h) about 5.5 m away horizontally.
  const double offset = (p - MbfFromGeographic(mars, {lat, lon, -1900.0})).norm();
  EXPECT_NEAR(offset, 1900.0 * (PlanetographicFromPlanetocentric(mars, lat) - lat) * -1.0, 0.05);
}

}  // namespace
}  // namespace areomap
