#include "areomap/map/projection.h"

#include <random>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "proj_oracle.h"

namespace areomap {
namespace {

using testing::RunProjTool;
using testing::ShellQuotedWkt;

constexpr int kPoints = 1000;
constexpr double kMetreTolerance = 1e-3;

// Planetocentric points; `hemisphere` +1/-1 restricts latitude to (1, 89.9) deg north/south.
std::vector<Geographic> RandomPoints(uint32_t seed, int hemisphere = 0) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> lat(hemisphere == 0 ? -89.0 : 1.0, 89.9);
  std::uniform_real_distribution<double> lon(-179.9, 179.9);
  std::vector<Geographic> out;
  for (int i = 0; i < kPoints; ++i) {
    const double lat_deg = hemisphere < 0 ? -lat(rng) : lat(rng);
    out.push_back({RadFromDeg(lat_deg), RadFromDeg(lon(rng)), 0.0});
  }
  return out;
}

// Compares MapProjection::Forward with `cs2cs SOURCE TARGET`, SOURCE a lat-first IAU
// geographic CRS, and checks Inverse() round trips.
void ExpectAgreesWithCs2cs(const MapProjection& projection, const std::string& source,
                           const std::string& target, const std::vector<Geographic>& points) {
  std::vector<Eigen::Vector3d> input;
  for (const auto& g : points) input.push_back({DegFromRad(g.lat), DegFromRad(g.lon), 0.0});
  const auto expected = RunProjTool("cs2cs -f %.6f " + source + " " + target, input);
  ASSERT_EQ(expected.size(), points.size());
  double worst = 0.0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector2d xy = projection.Forward(points[i]);
    worst = std::max(worst, (xy - expected[i].head<2>()).norm());
    const Geographic back = projection.Inverse(xy);
    EXPECT_LT((projection.Forward(back) - xy).norm(), 1e-6) << i;
    EXPECT_NEAR(back.lat, points[i].lat, 1e-12) << i;
  }
  EXPECT_LT(worst, kMetreTolerance) << "worst disagreement [m] with " << target;
}

TEST(MapProjection, EquirectangularAgreesWithIau49910) {
  ExpectAgreesWithCs2cs(MapProjection::Equirectangular(Body::MarsSphere(), 0.0, 0.0),
                        "IAU_2015:49900", "IAU_2015:49910", RandomPoints(1));
}

TEST(MapProjection, SphericalSinusoidalAgreesWithIau49920) {
  ExpectAgreesWithCs2cs(MapProjection::Sinusoidal(Body::MarsSphere(), 0.0), "IAU_2015:49900",
                        "IAU_2015:49920", RandomPoints(2));
}

TEST(MapProjection, EllipsoidalSinusoidalAgreesWithIau49922) {
  ExpectAgreesWithCs2cs(MapProjection::Sinusoidal(Body::Mars2000(), 0.0), "IAU_2015:49902",
                        "IAU_2015:49922", RandomPoints(3));
}

TEST(MapProjection, PolarStereographicAgreesWithIauNorthAndSouth) {
  const double half_pi = std::numbers::pi / 2;
  ExpectAgreesWithCs2cs(
      MapProjection::PolarStereographic(Body::MarsSphere(), Pole::kNorth, 0.0, half_pi),
      "IAU_2015:49900", "IAU_2015:49930", RandomPoints(4, +1));
  ExpectAgreesWithCs2cs(
      MapProjection::PolarStereographic(Body::MarsSphere(), Pole::kSouth, 0.0, -half_pi),
      "IAU_2015:49900", "IAU_2015:49935", RandomPoints(5, -1));
  ExpectAgreesWithCs2cs(
      MapProjection::PolarStereographic(Body::Mars2000(), Pole::kNorth, 0.0, half_pi),
      "IAU_2015:49902", "IAU_2015:49932", RandomPoints(6, +1));
  ExpectAgreesWithCs2cs(
      MapProjection::PolarStereographic(Body::Mars2000(), Pole::kSouth, 0.0, -half_pi),
      "IAU_2015:49902", "IAU_2015:49937", RandomPoints(7, -1));
}

TEST(MapProjection, WktDescribesWhatForwardComputes) {
  const std::vector<MapProjection> projections = {
      MapProjection::Equirectangular(Body::MarsSphere(), RadFromDeg(30.0), RadFromDeg(140.0)),
      MapProjection::Sinusoidal(Body::Mars2000(), RadFromDeg(141.5)),
      MapProjection::PolarStereographic(Body::Mars2000(), Pole::kNorth, RadFromDeg(-45.0),
                                        RadFromDeg(70.0)),
      MapProjection::PolarStereographic(Body::MarsSphere(), Pole::kSouth, RadFromDeg(120.0),
                                        RadFromDeg(-75.0)),
  };
  uint32_t seed = 10;
  for (const MapProjection& projection : projections) {
    const int hemisphere = projection.type() == ProjectionType::kPolarStereographic
                               ? (projection.center_lat() > 0 ? 1 : -1)
                               : 0;
    const std::string source =
        projection.surface() == Body::Mars2000() ? "IAU_2015:49902" : "IAU_2015:49900";
    ExpectAgreesWithCs2cs(projection, source, ShellQuotedWkt(projection.Wkt()),
                          RandomPoints(seed++, hemisphere));
  }
}

TEST(MapProjection, HiriseLocalRadiusEquirectangularAgreesWithProj) {
  const Body mars = Body::Mars2000();
  const double center_lat = RadFromDeg(-14.57);
  const MapProjection projection = MapProjection::Equirectangular(
      mars, center_lat, RadFromDeg(175.47), EquirectangularRadius::kLocalAtCenterLatitude);
  const double r = mars.RadiusAtPlanetocentricLatitude(center_lat);
  EXPECT_NEAR(projection.surface().a, r, 1e-9);
  EXPECT_GT(r, mars.b);
  EXPECT_LT(r, mars.a);
  const auto points = RandomPoints(20);
  std::vector<Eigen::Vector3d> input;
  for (const auto& g : points) input.push_back({DegFromRad(g.lon), DegFromRad(g.lat), 0.0});
  char args[256];
  std::snprintf(args, sizeof(args), "cct -d 6 +proj=eqc +R=%.9f +lat_ts=-14.57 +lon_0=175.47", r);
  const auto expected = RunProjTool(args, input);
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_LT((projection.Forward(points[i]) - expected[i].head<2>()).norm(), kMetreTolerance);
  }
}

TEST(MapProjection, UnmappablePointsGiveNaN) {
  const auto north = MapProjection::PolarStereographic(Body::MarsSphere(), Pole::kNorth, 0.0,
                                                       std::numbers::pi / 2);
  EXPECT_TRUE(north.Forward({-std::numbers::pi / 2, 0.0, 0.0}).hasNaN());
  EXPECT_TRUE(north.Forward({std::nan(""), 0.0, 0.0}).hasNaN());
  const auto sinusoidal = MapProjection::Sinusoidal(Body::Mars2000(), 0.0);
  EXPECT_TRUE(std::isnan(sinusoidal.Inverse({0.0, 1e8}).lat));
}

TEST(MapProjection, InvalidParametersAreRejectedWithTheirName) {
  try {
    MapProjection::PolarStereographic(Body::Mars2000(), Pole::kNorth, 0.0, RadFromDeg(-70.0));
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("latitude of true scale"), std::string::npos);
  }
  EXPECT_THROW(MapProjection::Equirectangular(Body::Mars2000(), RadFromDeg(91.0), 0.0), Error);
}

}  // namespace
}  // namespace areomap
