#include "areomap/map/line_of_sight.h"

#include <cmath>
#include <numbers>
#include <optional>
#include <string>

#include <gtest/gtest.h>

#include "test_support.h"

namespace areomap {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

// Ground (z down, the plane z = 0) with one hemispherical rock of radius 0.6 m centred 5 m
// ahead, seen from a camera 1.5 m above the origin.
double GroundHeight(double x, double y) {  // up, [m]
  const double r2 = (x - 5.0) * (x - 5.0) + y * y;
  return r2 < 0.36 ? std::sqrt(0.36 - r2) : 0.0;
}

const Eigen::Vector3d kCamera(0.0, 0.0, -1.5);

// Unit ray of azimuth `az` and elevation `el` [rad] (up positive) in the z-down frame.
Eigen::Vector3d Ray(double az, double el) {
  return {std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), -std::sin(el)};
}

// A point with an isotropic 1-sigma [m]; `left_x` -1 marks a mismatch the test adds.
StereoPoint PointAt(const Eigen::Vector3d& position, double sigma, float left_x = 0.0f) {
  StereoPoint p;
  p.position = position;
  p.covariance = sigma * sigma * Eigen::Matrix3d::Identity();
  p.left_x = left_x;
  return p;
}

// The first surface point along the ray of azimuth `az` and elevation `el` [rad] (marched in
// 1 mm steps up to 30 m), with a covariance like stereo's: sigma along the ray 0.002 r^2.
std::optional<StereoPoint> FirstHit(double az, double el) {
  const Eigen::Vector3d direction = Ray(az, el);
  for (double r = 0.5; r < 30.0; r += 0.001) {
    const Eigen::Vector3d p = kCamera + r * direction;
    if (-p.z() <= GroundHeight(p.x(), p.y())) {
      StereoPoint out;
      out.position = p;
      const double sigma = 0.002 * r * r;
      out.covariance =
          sigma * sigma * direction * direction.transpose() + 1e-6 * Eigen::Matrix3d::Identity();
      return out;
    }
  }
  return std::nullopt;
}

const PointCloud& VisibleScene() {
  static const PointCloud scene = [] {
    PointCloud cloud;
    cloud.camera_center = kCamera;
    for (double az = -20.03; az <= 20.0; az += 0.1) {  // off the 0.25 degree sector edges
      for (double el = -60.0; el <= -3.0; el += 0.5) {
        if (auto p = FirstHit(az * kDeg, el * kDeg)) cloud.points.push_back(*p);
      }
    }
    return cloud;
  }();
  return scene;
}

TEST(LineOfSight, KeepsEverySurfacePointTheCameraSees) {
  PointCloud cloud = VisibleScene();
  const size_t n = cloud.points.size();
  ASSERT_GT(n, 10000u);
  const LineOfSightDrops drops = DropLineOfSightConflicts(&cloud);
  EXPECT_EQ(drops.buried, 0u);
  EXPECT_EQ(drops.floating, 0u);
  EXPECT_EQ(cloud.points.size(), n);
}

TEST(LineOfSight, DropsMismatchesFarBelowTheGroundInFront) {
  PointCloud cloud = VisibleScene();
  const size_t n = cloud.points.size();
  // The rover's deck seen steeply down (40-55 degrees), matched as if 8-25 m away: metres
  // underground, as on the real K10 pair.
  int added = 0;
  for (double az = -15.0; az <= 15.0; az += 1.0) {
    for (double el = -55.0; el <= -40.0; el += 1.0, ++added) {
      const double r = 8.0 + 17.0 * (el + 55.0) / 15.0;
      cloud.points.push_back(
          PointAt(kCamera + r * Ray(az * kDeg, el * kDeg), 0.002 * r * r, -1.0f));
    }
  }
  const LineOfSightDrops drops = DropLineOfSightConflicts(&cloud);
  EXPECT_EQ(drops.buried, static_cast<size_t>(added));
  EXPECT_EQ(drops.floating, 0u);
  ASSERT_EQ(cloud.points.size(), n);
  for (const StereoPoint& p : cloud.points) EXPECT_NE(p.left_x, -1.0f);
}

TEST(LineOfSight, DropsMismatchesFloatingOverTheGroundBehind) {
  PointCloud cloud = VisibleScene();
  const size_t n = cloud.points.size();
  // A far building matched 3 m away, as on the real K10 pair: a cluster floating 2 m above the
  // ground, which would hide the ground the camera sees behind it. It buries no ground point:
  // those have the ground in front of them too.
  for (double az = -2.0; az <= 2.0; az += 0.1) {
    for (double dz = 0.0; dz < 0.5; dz += 0.1) {
      cloud.points.push_back(
          PointAt(Eigen::Vector3d(3.0 * std::cos(az * kDeg), 3.0 * std::sin(az * kDeg), -2.0 - dz),
                  0.01, -1.0f));
    }
  }
  const size_t floating = cloud.points.size() - n;
  const LineOfSightDrops drops = DropLineOfSightConflicts(&cloud);
  EXPECT_EQ(drops.floating, floating);
  EXPECT_EQ(drops.buried, 0u);
  ASSERT_EQ(cloud.points.size(), n);
  for (const StereoPoint& p : cloud.points) EXPECT_NE(p.left_x, -1.0f);
}

// At the image's edge the ground ends 4 m out; behind it lie only the rover deck's mismatches,
// far and steep. They are buried, and being buried they condemn none of the ground as floating.
TEST(LineOfSight, BuriedPointsAreNoWitnessesOfFloating) {
  PointCloud cloud;
  cloud.camera_center = kCamera;
  const Eigen::Vector3d along = Ray(45.0 * kDeg, 0.0);
  for (double rho = 1.0; rho <= 4.0; rho += 0.15) {
    cloud.points.push_back(PointAt(rho * along, 0.002 * rho * rho));
  }
  const size_t ground = cloud.points.size();
  for (double range = 12.0; range <= 17.0; range += 0.6) {
    cloud.points.push_back(
        PointAt(kCamera + range * Ray(45.0 * kDeg, -51.0 * kDeg), 0.002 * range * range));
  }
  const size_t deck = cloud.points.size() - ground;
  const LineOfSightDrops drops = DropLineOfSightConflicts(&cloud);
  EXPECT_EQ(drops.buried, deck);
  EXPECT_EQ(drops.floating, 0u);
  EXPECT_EQ(cloud.points.size(), ground);
}

TEST(LineOfSight, PointsBelowTheCameraAndLoneOnesAreKept) {
  PointCloud cloud;
  cloud.camera_center = kCamera;
  StereoPoint below;
  below.position = Eigen::Vector3d(0.001, 0.0, 0.0);
  cloud.points = {below, below};
  StereoPoint far;  // deep, but nothing in front of it
  far.position = Eigen::Vector3d(10.0, 0.0, 8.0);
  cloud.points.push_back(far);
  const LineOfSightDrops drops = DropLineOfSightConflicts(&cloud);
  EXPECT_EQ(drops.buried + drops.floating, 0u);
  EXPECT_EQ(cloud.points.size(), 3u);
}

TEST(LineOfSight, BadOptionsNameTheField) {
  PointCloud cloud;
  LineOfSightOptions options;
  options.sector_deg = 0.0;
  const std::string message =
      testing::ErrorMessageOf([&] { DropLineOfSightConflicts(&cloud, options); });
  EXPECT_NE(message.find("LineOfSightOptions.sector_deg"), std::string::npos) << message;
  options = {};
  options.max_fraction = 1.5;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              DropLineOfSightConflicts(&cloud, options);
            }).find("LineOfSightOptions.max_fraction"),
            std::string::npos);
}

}  // namespace
}  // namespace areomap
