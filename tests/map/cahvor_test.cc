#include "areomap/map/cahvor.h"

#include <random>

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/map/raster_description.h"
#include "test_support.h"

namespace areomap {
namespace {

// A Navcam-like CAHVOR (Table 1.1: 1024 x 1024, 0.76 mrad/px) looking along +x, 10 deg down.
CahvorModel NavcamLike() {
  const double f = 1.0 / 0.76e-3;
  const double tilt = RadFromDeg(10.0);
  const Eigen::Vector3d a(std::cos(tilt), 0.0, std::sin(tilt));  // z down (rover frame).
  const Eigen::Vector3d right(0.0, 1.0, 0.0);
  const Eigen::Vector3d down = a.cross(right);  // Image "down" (rover z points down).
  CahvorModel m;
  m.c = {0.5, 0.1, -1.5};
  m.a = a;
  m.h = f * right + 511.5 * a;
  m.v = f * down + 511.5 * a;
  m.o = (a + Eigen::Vector3d(0.0, 0.002, -0.003)).normalized();
  m.r = {0.0, -0.0025, 0.0185};  // The magnitudes of the real Navcam label's R.
  return m;
}

TEST(Cahvor, UnprojectThenProjectReturnsThePixel) {
  const CahvorModel m = NavcamLike();
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> px(0.0, 1023.0);
  std::uniform_real_distribution<double> range(0.5, 60.0);
  double worst = 0.0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector2d pixel(px(rng), px(rng));
    const Eigen::Vector3d ray = m.Unproject(pixel);
    EXPECT_NEAR(ray.norm(), 1.0, 1e-12);
    const auto back = m.Project(m.c + range(rng) * ray);
    ASSERT_TRUE(back.has_value());
    worst = std::max(worst, (*back - pixel).norm());
  }
  EXPECT_LT(worst, 1e-6);
}

TEST(Cahvor, PointsBehindTheCameraDoNotProject) {
  const CahvorModel m = NavcamLike();
  EXPECT_FALSE(m.Project(m.c - 3.0 * m.a).has_value());
  EXPECT_TRUE(m.Project(m.c + 3.0 * m.a).has_value());
}

TEST(Cahvor, ProjectIsDifferentiableByCeresJets) {
  const CahvorModel m = NavcamLike();
  using Jet = ceres::Jet<double, 3>;
  const Eigen::Vector3d p(6.0, 1.0, 0.8);
  const Eigen::Matrix<Jet, 3, 1> pj(Jet(p.x(), 0), Jet(p.y(), 1), Jet(p.z(), 2));
  Eigen::Matrix<Jet, 2, 1> pixel;
  ASSERT_TRUE(m.Project(pj, &pixel));
  for (int k = 0; k < 3; ++k) {
    const double step = 1e-6;
    const Eigen::Vector3d dp = Eigen::Vector3d::Unit(k) * step;
    const Eigen::Vector2d numeric = (*m.Project(p + dp) - *m.Project(p - dp)) / (2.0 * step);
    EXPECT_NEAR(pixel(0).v[k], numeric.x(), 1e-4);
    EXPECT_NEAR(pixel(1).v[k], numeric.y(), 1e-4);
  }
}

TEST(Cahvor, RealNavcamLabelHasNavcamGeometry) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto path = testing::SharedDataDir() / "mer" / "1N491020376ILFCNY9P0706L0M1.IMG";
  const RasterDescription d = DescribeRaster(path);
  ASSERT_TRUE(d.product && d.product->camera);
  const CahvorModel m = CahvorFromLabel(*d.product->camera, path.string());
  EXPECT_TRUE(m.HasDistortion());
  // Table 1.1's 14.67 mm focal length on the MER CCD's 12 um pixels is 0.818 mrad/px (Table
  // 1.1 rounds the IFOV to 0.76 from 45 deg / 1024 px); the axis is near the detector centre.
  const double ifov = 12e-6 / 14.67e-3;
  EXPECT_NEAR(1.0 / m.FocalLengths().x(), ifov, 0.02 * ifov);
  EXPECT_NEAR(1.0 / m.FocalLengths().y(), ifov, 0.02 * ifov);
  EXPECT_NEAR(m.PrincipalPoint().x(), 511.5, 20.0);
  EXPECT_NEAR(m.PrincipalPoint().y(), 511.5, 20.0);
  // Moving the camera into the site frame with the label's rover->site pose keeps every
  // pixel's view of a point expressed in both frames.
  const auto rover = std::find_if(d.product->frames.begin(), d.product->frames.end(),
                                  [](const auto& f) { return f.name == "ROVER_FRAME"; });
  ASSERT_NE(rover, d.product->frames.end());
  const CahvorModel in_site = m.Transformed(rover->reference_from_frame);
  const Eigen::Vector3d p_in_rover = m.c + 8.0 * m.Unproject({300.0, 700.0});
  const auto pixel = in_site.Project(rover->reference_from_frame * p_in_rover);
  ASSERT_TRUE(pixel.has_value());
  EXPECT_LT((*pixel - Eigen::Vector2d(300.0, 700.0)).norm(), 1e-6);
}

TEST(Cahvor, OtherModelTypesAreRejectedWithTheFileName) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto path = testing::SharedDataDir() / "mer" / "1F490747543EFFCNY9P1214L0M1.IMG";
  const RasterDescription d = DescribeRaster(path);
  ASSERT_TRUE(d.product && d.product->camera);
  const std::string message =
      testing::ErrorMessageOf([&] { CahvorFromLabel(*d.product->camera, path.string()); });
  EXPECT_NE(message.find("1F490747543EFFCNY9P1214L0M1.IMG: camera model type CAHVORE"),
            std::string::npos)
      << message;
}

}  // namespace
}  // namespace areomap
