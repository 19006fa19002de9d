#include "areomap/samples/rover.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/interest_points.h"
#include "areomap/map/pds_label.h"
#include "areomap/map/sparse_stereo.h"
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

// Ch. 2.2.2's stereo tie points: Förstner interest points of the left image matched along the
// epipolar curve with the Table 4.5 filters. Accepted points must be as accurate as the range
// error model says (eq. 4.3, sigma_p = 0.5 px), and the filters must keep most of them.
// (Called by the test below on its rendered pair: rendering is most of the cost.)
void ExpectForstnerTiePointsWithinTheRangeErrorModel(const StereoFixture& f, const cv::Mat& left,
                                                     const cv::Mat& right) {
  const double baseline = 0.20, focal = f.cameras[0].FocalLengths().x();
  const std::vector<InterestPoint> points = DetectForstnerPoints(left);
  ASSERT_GE(points.size(), 300u);
  SparseStereoOptions options;
  options.min_texture = 15.0;
  const std::vector<SparseTiePoint> ties =
      MatchInterestPoints(left, right, f.cameras[0], f.cameras[1], points, options);
  ASSERT_EQ(ties.size(), points.size());
  std::vector<double> normalized_errors;
  int accepted = 0;
  for (const SparseTiePoint& tie : ties) {
    if (!tie.match.ok) continue;
    ++accepted;
    EXPECT_GE(tie.match.correlation, 0.85);
    const int x = static_cast<int>(std::lround(tie.left.pixel.x()));
    const int y = static_cast<int>(std::lround(tie.left.pixel.y()));
    const double truth = f.images[0].range.at<float>(y, x);
    if (!std::isfinite(truth) || truth < 3.0 || truth > 25.0) continue;
    const double sigma_r = truth * truth * 0.5 / (baseline * focal);
    normalized_errors.push_back(std::abs(tie.match.range_m - truth) / sigma_r);
  }
  ::testing::Test::RecordProperty("forstner_points", std::to_string(points.size()));
  ::testing::Test::RecordProperty("forstner_accepted", std::to_string(accepted));
  EXPECT_GE(accepted, static_cast<int>(points.size()) / 2) << "the filters rejected most points";
  ASSERT_GE(normalized_errors.size(), 100u);
  std::sort(normalized_errors.begin(), normalized_errors.end());
  ::testing::Test::RecordProperty("forstner_median_abs_error_over_sigma_r",
                                  std::to_string(normalized_errors[normalized_errors.size() / 2]));
  ::testing::Test::RecordProperty(
      "forstner_p90_abs_error_over_sigma_r",
      std::to_string(normalized_errors[normalized_errors.size() * 9 / 10]));
  // The truth is the range at the nearest pixel centre, up to half a pixel from the interest
  // point: on slanted ground that adds little, at rock outlines it can add metres, hence p90.
  EXPECT_LT(normalized_errors[normalized_errors.size() / 2], 1.0) << "median |error| / sigma_r";
  EXPECT_LT(normalized_errors[normalized_errors.size() * 9 / 10], 3.0) << "p90 |error| / sigma_r";
}

// Sparse stereo with the true cameras (MatchPixel: epipolar search, 11x11 NCC, Table 4.5
// filters), compared with the rendered truth. Eq. 4.3: sigma_r = r^2 sigma_p / (b f), with
// sigma_p = 0.5 px.
TEST(SiteMesh, StereoPairsTriangulateToTheTruthWithinTheRangeErrorModel) {
  const StereoFixture f(RadFromDeg(20.0));
  const double baseline = 0.20, focal = f.cameras[0].FocalLengths().x();
  cv::Mat left, right;
  f.images[0].dn.convertTo(left, CV_32F);
  f.images[1].dn.convertTo(right, CV_32F);
  SparseStereoOptions options;
  options.min_texture = 15.0;  // DN: a matcher skips flat windows.
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> px(40, 983);
  std::vector<double> normalized_errors;
  int rejected = 0;
  for (int trial = 0; trial < 3000 && normalized_errors.size() < 150; ++trial) {
    const int x = px(rng), y = px(rng);
    const double truth = f.images[0].range.at<float>(y, x);
    if (!std::isfinite(truth) || truth < 3.0 || truth > 25.0) continue;
    const SparseStereoMatch match =
        MatchPixel(left, right, f.cameras[0], f.cameras[1], Eigen::Vector2d(x, y), options);
    if (!match.ok) {
      if (match.rejected_by != "texture") ++rejected;
      continue;
    }
    EXPECT_LT(std::abs(match.vertical_disparity_px), 4.0);
    const double sigma_r = truth * truth * 0.5 / (baseline * focal);
    normalized_errors.push_back(std::abs(match.range_m - truth) / sigma_r);
  }
  ASSERT_GE(normalized_errors.size(), 100u);
  std::sort(normalized_errors.begin(), normalized_errors.end());
  const double median = normalized_errors[normalized_errors.size() / 2];
  const double p95 = normalized_errors[normalized_errors.size() * 95 / 100];
  ::testing::Test::RecordProperty("median_abs_error_over_sigma_r", std::to_string(median));
  ::testing::Test::RecordProperty("p95_abs_error_over_sigma_r", std::to_string(p95));
  ::testing::Test::RecordProperty("matched", std::to_string(normalized_errors.size()));
  ::testing::Test::RecordProperty("rejected_by_filters", std::to_string(rejected));
  // |error| / sigma_r of a normal error has median 0.67 and 95th percentile 1.96.
  EXPECT_LT(median, 1.0) << "median |range error| / sigma_r";
  EXPECT_LT(p95, 3.0) << "95th percentile |range error| / sigma_r";
  // The filters keep most textured points.
  EXPECT_LT(rejected, static_cast<int>(normalized_errors.size()) / 2);

  ExpectForstnerTiePointsWithinTheRangeErrorModel(f, left, right);
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
