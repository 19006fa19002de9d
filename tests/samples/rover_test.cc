#include "areomap/samples/rover.h"

#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/pds_label.h"
#include "areomap/samples/mission.h"
#include "test_support.h"

namespace areomap {
namespace {

// A 60 m scene with gentle relief and rocks near the origin; the rover stands at the origin
// facing north and the Navcam looks at `azimuth` (rover frame) 30 degrees down.
struct StereoFixture {
  Scene scene;
  SiteMesh mesh;
  std::array<CahvorModel, 2> cameras;  // In ENU.
  std::array<SiteMesh::Image, 2> images;

  static SceneOptions Options() {
    SceneOptions o;
    o.half_extent_m = 60.0;
    o.crater_count = 0;
    o.roughness_m = 0.3;
    o.rock_path = {{0.0, 0.0}, {0.0, 20.0}};
    o.rock_corridor_m = 12.0;
    return o;
  }
  explicit StereoFixture(double azimuth)
      : scene(Options()), mesh(scene, {0.0, 0.0, scene.GroundHeightAt(0.0, 0.0)}, RenderOptions{}) {
    Eigen::Matrix3d enu_from_rover;  // Facing north: x -> north, y -> east, z -> down.
    enu_from_rover << 0, 1, 0, 1, 0, 0, 0, 0, -1;
    const Rigid3d enu_from_rover_pose(enu_from_rover,
                                      Eigen::Vector3d(0, 0, scene.GroundHeightAt(0.0, 0.0)));
    const auto in_rover = StereoCameras(StereoCameraOptions{}, {azimuth, RadFromDeg(-30.0)});
    for (int i = 0; i < 2; ++i) {
      cameras[i] = in_rover[i].Transformed(enu_from_rover_pose);
      images[i] = mesh.Render(cameras[i], 1024, 1024, 11u + static_cast<uint32_t>(i));
    }
  }
};

TEST(StereoCameras, NavcamHeadMatchesTableOneOne) {
  const StereoCameraOptions navcam;
  EXPECT_NEAR(navcam.FieldOfViewDeg(), 45.4, 0.1);  // Table 1.1: 45 deg.
  const auto cameras = StereoCameras(navcam, {RadFromDeg(30.0), RadFromDeg(-20.0)});
  EXPECT_NEAR((cameras[1].c - cameras[0].c).norm(), 0.20, 1e-12);  // 20 cm baseline.
  EXPECT_NEAR((cameras[1].c - cameras[0].c).dot(cameras[0].a), 0.0, 1e-12);
  EXPECT_NEAR(cameras[0].PrincipalPoint().x(), 511.5, 1e-9);
  EXPECT_NEAR(1.0 / cameras[0].FocalLengths().x(), 12e-6 / 14.67e-3, 1e-12);
  // Looking 20 degrees down: the axis has a positive z (down) component in the rover frame.
  EXPECT_NEAR(std::asin(cameras[0].a.z()), RadFromDeg(20.0), 1e-12);
  StereoCameraOptions wide;
  wide.field_of_view_deg = 180.0;
  EXPECT_NE(testing::ErrorMessageOf([&] { wide.Check(); }).find("field_of_view_deg"),
            std::string::npos);
}

TEST(SiteMesh, RenderedRangesLieOnTheTrueSurface) {
  const StereoFixture f(0.0);
  const cv::Mat& range = f.images[0].range;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> px(0, 1023);
  int checked = 0;
  double worst = 0.0;
  for (int i = 0; i < 4000; ++i) {
    const int x = px(rng), y = px(rng);
    const float r = range.at<float>(y, x);
    if (!std::isfinite(r) || r > 7.5f) continue;  // Inside the 2 cm ring.
    const Eigen::Vector3d p = f.cameras[0].c + r * f.cameras[0].Unproject({x, y});
    worst = std::max(worst, std::abs(p.z() - f.scene.HeightAt(p.x(), p.y())));
    ++checked;
  }
  EXPECT_GT(checked, 1000);
  // The mesh interpolates the surface linearly between 2 cm vertices; rock flanks are steep.
  EXPECT_LT(worst, 0.03);
}

// Sparse stereo with the true cameras: search the right image along each left pixel's
// epipolar curve (0.25 px disparity steps, 11x11 NCC, parabola refinement), triangulate, and
// compare with the rendered truth. Eq. 4.3: sigma_r = r^2 sigma_p / (b f), sigma_p = 0.5 px.
TEST(SiteMesh, StereoPairsTriangulateToTheTruthWithinTheRangeErrorModel) {
  const StereoFixture f(RadFromDeg(20.0));
  cv::Mat left, right;
  f.images[0].dn.convertTo(left, CV_32F);
  f.images[1].dn.convertTo(right, CV_32F);
  const double baseline = 0.20, focal = f.cameras[0].FocalLengths().x();
  const int half = 5;
  const auto patch = [&](const cv::Mat& image, double x, double y) {
    cv::Mat out;
    cv::getRectSubPix(image, cv::Size(2 * half + 1, 2 * half + 1),
                      cv::Point2f(static_cast<float>(x), static_cast<float>(y)), out);
    return out;
  };
  const auto ncc = [](const cv::Mat& a, const cv::Mat& b) {
    cv::Mat result;
    cv::matchTemplate(a, b, result, cv::TM_CCOEFF_NORMED);
    return static_cast<double>(result.at<float>(0, 0));
  };
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> px(40, 983);
  std::vector<double> normalized_errors;
  for (int trial = 0; trial < 3000 && normalized_errors.size() < 150; ++trial) {
    const int x = px(rng), y = px(rng);
    const double truth = f.images[0].range.at<float>(y, x);
    if (!std::isfinite(truth) || truth < 3.0 || truth > 25.0) continue;
    const cv::Mat reference = patch(left, x, y);
    cv::Scalar mean, stddev;
    cv::meanStdDev(reference, mean, stddev);
    if (stddev[0] < 15.0) continue;  // Textureless: a matcher would reject it too.
    const Eigen::Vector3d ray = f.cameras[0].Unproject({x, y});
    std::vector<double> disparities, scores;
    for (double d = 6.0; d <= 110.0; d += 0.25) {
      const auto q =
          f.cameras[1].Project(Eigen::Vector3d(f.cameras[0].c + baseline * focal / d * ray));
      if (!q || q->x() < half || q->y() < half || q->x() > 1023 - half || q->y() > 1023 - half) {
        continue;
      }
      disparities.push_back(d);
      scores.push_back(ncc(reference, patch(right, q->x(), q->y())));
    }
    if (scores.size() < 3) continue;
    const auto best = std::max_element(scores.begin() + 1, scores.end() - 1) - scores.begin();
    if (scores[best] < 0.85) continue;  // Table 4.5: correlation >= 0.85.
    const double s0 = scores[best - 1], s1 = scores[best], s2 = scores[best + 1];
    const double offset = 0.5 * (s0 - s2) / (s0 - 2.0 * s1 + s2);
    const double disparity = disparities[best] + 0.25 * std::clamp(offset, -1.0, 1.0);
    const double range = baseline * focal / disparity;
    const double sigma_r = truth * truth * 0.5 / (baseline * focal);
    normalized_errors.push_back(std::abs(range - truth) / sigma_r);
  }
  ASSERT_GE(normalized_errors.size(), 100u);
  std::sort(normalized_errors.begin(), normalized_errors.end());
  const double median = normalized_errors[normalized_errors.size() / 2];
  const double p95 = normalized_errors[normalized_errors.size() * 95 / 100];
  ::testing::Test::RecordProperty("median_abs_error_over_sigma_r", std::to_string(median));
  ::testing::Test::RecordProperty("p95_abs_error_over_sigma_r", std::to_string(p95));
  ::testing::Test::RecordProperty("points", std::to_string(normalized_errors.size()));
  // |error| / sigma_r of a normal error has median 0.67 and 95th percentile 1.96.
  EXPECT_LT(median, 1.0) << "median |range error| / sigma_r";
  EXPECT_LT(p95, 3.0) << "95th percentile |range error| / sigma_r";
}

TEST(RoverImageLabel, ReadsBackThroughTheMerLabelParser) {
  const auto cameras = StereoCameras(StereoCameraOptions{}, {0.3, -0.4});
  const Rigid3d site_from_rover(
      Eigen::Quaterniond(Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ())),
      Eigen::Vector3d::Zero());
  const auto label =
      RoverImageLabel("NAVCAM_RIGHT", 7, cameras[1], site_from_rover, 1024, 1024, 12);
  const ProductGeometry geometry = ParseProductGeometry(label, "label.json");
  ASSERT_TRUE(geometry.camera.has_value());
  const CahvorModel back = CahvorFromLabel(*geometry.camera, "label.json");
  EXPECT_LT((back.c - cameras[1].c).norm(), 1e-12);
  EXPECT_LT((back.h - cameras[1].h).norm(), 1e-9);
  EXPECT_LT((back.r - cameras[1].r).norm(), 1e-15);
  ASSERT_EQ(geometry.frames.size(), 1u);
  EXPECT_EQ(geometry.frames[0].reference_frame, "SITE_FRAME");
  EXPECT_EQ(geometry.frames[0].index, std::vector<int>{7});
  EXPECT_LT(
      geometry.frames[0].reference_from_frame.rotation.angularDistance(site_from_rover.rotation),
      1e-12);
}

}  // namespace
}  // namespace areomap
