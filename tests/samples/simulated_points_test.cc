#include "areomap/samples/simulated_points.h"

#include <cmath>

#include <gtest/gtest.h>

#include "areomap/map/error.h"

namespace areomap {
namespace {

Scene SmallScene() {
  SceneOptions options;
  options.half_extent_m = 60.0;
  options.crater_count = 2;
  options.rock_path = {Eigen::Vector2d(-40, 0), Eigen::Vector2d(40, 0)};
  options.rock_abundance_k = 0.1;
  return Scene(options);
}

TEST(SimulatedPoints, NoiseFreePointsLieOnTheTerrainWithinTheRangeLimits) {
  const Scene scene = SmallScene();
  SimulatedPointsOptions options;
  options.noise = false;
  options.azimuth_max_deg = 90.0;
  const Eigen::Vector2d site(5.0, -3.0);
  const PointCloud cloud = SimulateSitePointCloud(scene, site, 4, options);
  ASSERT_GT(cloud.points.size(), 1000u);
  EXPECT_EQ(cloud.site, 4);
  EXPECT_DOUBLE_EQ(cloud.camera_center.z(), -options.camera_height_m);
  const double ground = scene.GroundHeightAt(site.x(), site.y());
  for (const StereoPoint& p : cloud.points) {
    // Site frame: x north, y east, z down from the ground under the camera.
    const double east = site.x() + p.position.y(), north = site.y() + p.position.x();
    EXPECT_NEAR(-p.position.z(), scene.HeightAt(east, north) - ground, 1e-9);
    const double horizontal = p.position.head<2>().norm();
    EXPECT_GE(horizontal, options.min_range_m - 1e-9);
    EXPECT_LE(horizontal, options.max_range_m + 1e-9);
    EXPECT_GE(p.position.x(), -1e-9);  // Azimuth 0..90: north-east quadrant.
    EXPECT_GE(p.position.y(), -1e-9);
  }
  CheckPointCloud(cloud, "simulated");
}

TEST(SimulatedPoints, NoiseFollowsTheStereoCovariance) {
  const Scene scene = SmallScene();
  SimulatedPointsOptions options;
  options.azimuth_max_deg = 60.0;
  options.seed = 7;
  const Eigen::Vector2d site(0.0, 0.0);
  const PointCloud noisy = SimulateSitePointCloud(scene, site, 0, options);
  options.noise = false;
  const PointCloud truth = SimulateSitePointCloud(scene, site, 0, options);
  ASSERT_EQ(noisy.points.size(), truth.points.size());
  double chi2 = 0.0;
  for (size_t i = 0; i < noisy.points.size(); ++i) {
    const Eigen::Vector3d e = noisy.points[i].position - truth.points[i].position;
    chi2 += e.dot(noisy.points[i].covariance.inverse() * e);
  }
  // Mean of a chi-square with 3 degrees of freedom is 3; its standard error over n points is
  // sqrt(6 / n), well under 0.1 here.
  EXPECT_NEAR(chi2 / static_cast<double>(noisy.points.size()), 3.0, 0.15);
}

TEST(SimulatedPoints, RejectsInvalidOptions) {
  const Scene scene = SmallScene();
  SimulatedPointsOptions options;
  options.max_range_m = 1.0;
  EXPECT_THROW(SimulateSitePointCloud(scene, {0, 0}, 0, options), Error);
}

TEST(PointCloud, CheckNamesTheSourceAndTheBadPoint) {
  PointCloud cloud;
  EXPECT_THROW(CheckPointCloud(cloud, "a.ply"), Error);
  cloud.points.resize(3);
  cloud.points[2].position.x() = std::nan("");
  try {
    CheckPointCloud(cloud, "a.ply");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a.ply: point 2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace areomap

namespace areomap {
namespace {

TEST(PointCloud, ThinningKeepsAboutOnePointPerGroundSpacing) {
  PointCloud cloud;
  for (int row = 0; row < 40; ++row) {
    for (int col = 0; col < 40; ++col) {
      StereoPoint near;  // 2 m away: 1000 px focal length -> 2 mm pixels.
      near.position = Eigen::Vector3d(2.0, 0.0, 0.0);
      near.left_x = static_cast<float>(col);
      near.left_y = static_cast<float>(row);
      StereoPoint far = near;  // 20 m away: 2 cm pixels, coarser than the spacing.
      far.position = Eigen::Vector3d(20.0, 0.0, 0.0);
      cloud.points.push_back(near);
      cloud.points.push_back(far);
    }
  }
  const PointCloud thinned = ThinToGroundSpacing(cloud, 0.01, 1000.0);
  int near_kept = 0, far_kept = 0;
  for (const StereoPoint& p : thinned.points) {
    if (p.position.x() < 10.0) {
      ++near_kept;
      EXPECT_EQ(static_cast<int>(p.left_x) % 5, 0);  // Step round(0.01 * 1000 / 2) = 5 px.
      EXPECT_EQ(static_cast<int>(p.left_y) % 5, 0);
    } else {
      ++far_kept;
    }
  }
  EXPECT_EQ(near_kept, 8 * 8);
  EXPECT_EQ(far_kept, 40 * 40);
  EXPECT_THROW(ThinToGroundSpacing(cloud, 0.0, 1000.0), Error);
}

}  // namespace
}  // namespace areomap
