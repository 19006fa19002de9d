#include "areomap/map/stereo_error.h"

#include <random>

#include <gtest/gtest.h>

#include "areomap/map/cahvor.h"
#include "areomap/map/error.h"
#include "test_support.h"

namespace areomap {
namespace {

TEST(StereoError, RangeSigmaIsEquationFourThree) {
  // Navcam: b = 0.2 m, f = 14.67 mm / 12 um = 1222.5 px, sigma_p = 0.5 px.
  EXPECT_NEAR(StereoRangeSigma(27.0, 0.2, 1222.5, 0.5), 27.0 * 27.0 * 0.5 / 244.5, 1e-12);
  EXPECT_NEAR(StereoRangeSigma(27.0, 0.2, 1222.5, 0.5), 1.491, 1e-3);
  EXPECT_NEAR(StereoRangeSigma(38.0, 0.2, 1222.5, 0.5), 2.953, 1e-3);
}

TEST(StereoError, HorizontalCovarianceIsEquationFourTwo) {
  const StereoErrorModel model;
  const double r = 15.0, theta = 0.7;  // Azimuth from north (x) toward east (y).
  const Eigen::Vector3d point(r * std::cos(theta), r * std::sin(theta), 0.0);
  const Eigen::Matrix3d cov = StereoPointCovariance(point, Eigen::Vector3d::Zero(), model);
  const double sr = StereoRangeSigma(r, model.baseline_m, model.focal_px, model.parallax_sigma_px);
  const double st = model.azimuth_sigma_px / model.focal_px;  // [rad]
  const double c = std::cos(theta), s = std::sin(theta);
  EXPECT_NEAR(cov(0, 0), c * c * sr * sr + r * r * s * s * st * st, 1e-12);
  EXPECT_NEAR(cov(0, 1), s * c * sr * sr - r * r * s * c * st * st, 1e-12);
  EXPECT_NEAR(cov(1, 1), s * s * sr * sr + r * r * c * c * st * st, 1e-12);
}

TEST(StereoError, TriangulatedRangeScatterMatchesTheModel) {
  // Two parallel pinhole cameras 20 cm apart looking along +x; disparity noise sigma_p = 0.5 px.
  const double f = 1222.5, b = 0.2, sigma_p = 0.5;
  CahvorModel left;
  left.a = Eigen::Vector3d::UnitX();
  left.h = f * Eigen::Vector3d::UnitY() + 511.5 * left.a;
  left.v = f * Eigen::Vector3d::UnitZ() + 511.5 * left.a;
  left.o = left.a;
  CahvorModel right = left;
  right.c = Eigen::Vector3d(0.0, b, 0.0);
  std::mt19937 rng(9);
  std::normal_distribution<double> noise(0.0, sigma_p / std::sqrt(2.0));  // Per image.
  for (const double range : {5.0, 15.0, 25.0}) {
    const Eigen::Vector3d truth(range, 0.3, 0.2);
    double sum = 0.0, sum2 = 0.0;
    int n = 0;
    for (int i = 0; i < 4000; ++i) {
      const Eigen::Vector2d pl = *left.Project(truth) + Eigen::Vector2d(noise(rng), 0.0);
      const Eigen::Vector2d pr = *right.Project(truth) + Eigen::Vector2d(noise(rng), 0.0);
      const auto hit = TriangulateRays(left.c, left.Unproject(pl), right.c, right.Unproject(pr));
      ASSERT_TRUE(hit.has_value());
      const double error = hit->range_first_m - truth.norm();
      sum += error;
      sum2 += error * error;
      ++n;
    }
    const double empirical = std::sqrt(sum2 / n - (sum / n) * (sum / n));
    const double model = StereoRangeSigma(truth.norm(), b, f, sigma_p);
    EXPECT_NEAR(empirical, model, 0.1 * model) << "range " << range;
  }
}

TEST(StereoError, TriangulationRejectsParallelAndBackwardRays) {
  const Eigen::Vector3d c1(0, 0, 0), c2(0, 0.2, 0);
  EXPECT_FALSE(TriangulateRays(c1, {1, 0, 0}, c2, {1, 0, 0}).has_value());
  // Diverging rays meet only behind the cameras.
  EXPECT_FALSE(TriangulateRays(c1, {1, -0.01, 0}, c2, {1, 0.01, 0}).has_value());
  const auto hit = TriangulateRays(c1, {10, 0.1, 0}, c2, {10, -0.1, 0});
  ASSERT_TRUE(hit.has_value());
  EXPECT_LT((hit->point - Eigen::Vector3d(10, 0.1, 0)).norm(), 1e-9);
  EXPECT_LT(hit->gap_m, 1e-12);
  StereoErrorModel bad;
  bad.baseline_m = 0.0;
  EXPECT_NE(testing::ErrorMessageOf([&] { bad.Check(); }).find("StereoErrorModel.baseline_m"),
            std::string::npos);
}

}  // namespace
}  // namespace areomap

#include "areomap/map/sparse_stereo.h"

namespace areomap {
namespace {

TEST(SparseStereo, RejectsUnsupportedImagesAndNamesBadOptions) {
  const cv::Mat sixteen_bit(64, 64, CV_16U, cv::Scalar(100));
  CahvorModel camera;
  camera.h = 100.0 * Eigen::Vector3d::UnitY() + 32.0 * camera.a;
  camera.v = 100.0 * Eigen::Vector3d::UnitZ() + 32.0 * camera.a;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              MatchPixel(sixteen_bit, sixteen_bit, camera, camera, {32, 32});
            }).find("CV_8U or CV_32F"),
            std::string::npos);
  SparseStereoOptions options;
  options.max_range_m = 0.5;
  EXPECT_NE(
      testing::ErrorMessageOf([&] { options.Check(); }).find("SparseStereoOptions.min_range_m"),
      std::string::npos);
  // A flat window is rejected by the texture filter, not matched.
  const cv::Mat flat(64, 64, CV_32F, cv::Scalar(100));
  const SparseStereoMatch match = MatchPixel(flat, flat, camera, camera, {32, 32});
  EXPECT_FALSE(match.ok);
  EXPECT_EQ(match.rejected_by, "texture");
}

}  // namespace
}  // namespace areomap
