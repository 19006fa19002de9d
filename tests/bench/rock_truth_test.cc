// The truth rules the rock benches judge tie points by (bench/rock_truth.h): which truth rock a
// stereo peak was seen on.
#include "rock_truth.h"

#include <fstream>

#include <gtest/gtest.h>

#include "test_support.h"

namespace areomap::bench {
namespace {

// Site 0's frame: x north, y east, z down [m], origin on the ellipsoid (height 0). The camera is
// 1.5 m above the origin; every rock stands on ground at height 0.
const Eigen::Vector3d kCamera(0.0, 0.0, -1.5);

TruthRock Hemispheroid(int id, double north, double east, double radius, double height) {
  Rock shape;
  shape.id = id;
  shape.shape = RockShape::kHemispheroid;
  shape.center = Eigen::Vector2d(east, north);  // ENU.
  shape.a = shape.b = radius;
  shape.height = height;
  return {id, Eigen::Vector2d(north, east), height, radius, 0.0, shape};
}

Eigen::Vector3d Top(const TruthRock& r) {
  return Eigen::Vector3d(r.north_east.x(), r.north_east.y(), -r.height);
}

// `point` moved `metres` along the camera's ray through it (away from the camera positive).
Eigen::Vector3d AlongRay(const Eigen::Vector3d& point, double metres) {
  return point + metres * (point - kCamera).normalized();
}

// A far Navcam peak: 0.5 m sigma along its line of sight [m].
constexpr double kFarPeakSigma = 0.5;

TEST(SightRayTruth, FarPeakBelongsToTheRockItsRayMeetsWhereverAlongTheRayItLies) {
  // A: 20 cm high, 40 cm wide, 15 m out. B: taller, 40 cm east of A (their footprints 5 cm apart).
  const std::vector<TruthRock> truth = {Hemispheroid(1, 15.0, 0.0, 0.20, 0.20),
                                        Hemispheroid(2, 15.0, 0.40, 0.15, 0.25)};
  const SightRayTruth sight(truth, /*origin_height=*/0.0);
  for (double along : {-1.0, -0.5, 0.0, 0.3, 1.0}) {
    EXPECT_EQ(sight.RockSeen(kCamera, AlongRay(Top(truth[0]), along), kFarPeakSigma), 1) << along;
    EXPECT_EQ(sight.RockSeen(kCamera, AlongRay(Top(truth[1]), along), kFarPeakSigma), 2) << along;
  }
  // The disk rule gives A's peak measured 30 cm beyond A to the taller B.
  const Eigen::Vector3d beyond = AlongRay(Top(truth[0]), 0.3);
  EXPECT_EQ(RockUnder(truth, beyond.head<2>(), 0.5), 2);
}

TEST(SightRayTruth, PeakOnTheGroundOrFarAboveARockIsOnNone) {
  const std::vector<TruthRock> truth = {Hemispheroid(1, 15.0, 0.0, 0.20, 0.20)};
  const SightRayTruth sight(truth, 0.0);
  // On the ground 1 m west of the rock.
  EXPECT_EQ(sight.RockSeen(kCamera, Eigen::Vector3d(15.0, -1.0, 0.0), kFarPeakSigma), -1);
  // Beyond 4 sigma along the ray (the ray meets the rock 2.5 m before the peak).
  EXPECT_EQ(sight.RockSeen(kCamera, AlongRay(Top(truth[0]), 2.5), kFarPeakSigma), -1);
  // The block matcher's foreground fattening: the background 2 px above the top is given the
  // rock's range; 15 px above is another thing.
  const double ifov = 12.0e-6 / 14.67e-3;
  const double range = (Top(truth[0]) - kCamera).norm();
  const Eigen::Vector3d two_px_above = Top(truth[0]) - Eigen::Vector3d(0, 0, 2 * ifov * range);
  const Eigen::Vector3d fifteen_px_above = Top(truth[0]) - Eigen::Vector3d(0, 0, 15 * ifov * range);
  EXPECT_EQ(sight.RockSeen(kCamera, two_px_above, kFarPeakSigma), 1);
  EXPECT_EQ(sight.RockSeen(kCamera, fifteen_px_above, kFarPeakSigma), -1);
}

TEST(ReadTruthRocks, ReadsTheGeneratorsShapesAndNamesAMalformedFile) {
  const areomap::testing::TempDir dir;
  const std::filesystem::path csv = dir.path() / "rocks.csv";
  std::ofstream(csv)
      << "id,shape,east_m,north_m,ground_z_m,height_m,a_m,b_m,azimuth_deg,tilt_x_deg,tilt_y_deg\n"
      << "7,semi-ellipsoid,3.0,4.0,-1900.5,0.3,0.4,0.2,90,10,0\n";
  const std::vector<TruthRock> rocks = ReadTruthRocks(csv);
  ASSERT_EQ(rocks.size(), 1u);
  EXPECT_EQ(rocks[0].north_east, Eigen::Vector2d(4.0, 3.0));
  EXPECT_EQ(rocks[0].shape.shape, RockShape::kSemiEllipsoid);
  EXPECT_NEAR(rocks[0].shape.azimuth, std::numbers::pi / 2, 1e-12);
  EXPECT_NEAR(rocks[0].shape.tilt_x, std::numbers::pi / 18, 1e-12);
  EXPECT_DOUBLE_EQ(rocks[0].shape.b, 0.2);
  std::ofstream(csv) << "id,shape,east_m,north_m,ground_z_m,height_m,a_m\n"
                     << "7,cone,3.0,4.0,-1900.5,0.3,0.4\n";
  const std::string message = areomap::testing::ErrorMessageOf([&] { ReadTruthRocks(csv); });
  EXPECT_NE(message.find(csv.string()), std::string::npos) << message;
  EXPECT_NE(message.find("expected 11 fields"), std::string::npos) << message;
}

}  // namespace
}  // namespace areomap::bench
