// Dense stereo on rendered pairs (the generator's terrain and cameras: known truth) and on bad
// input. Thresholds come from eq. 4.3: sigma_r = r^2 sigma_p / (b f), sigma_p = 0.5 px.
#include "areomap/map/dense_stereo.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/image_io.h"
#include "areomap/map/rectification.h"
#include "areomap/samples/rover.h"
#include "areomap/samples/scene.h"
#include "k10_pavement.h"
#include "test_support.h"

namespace areomap {
namespace {

// A Navcam-like head (45 degree field of view) at `size` px looking `azimuth` from north, 15
// degrees down, over a 60 m scene with rocks. The rover frame is the site frame (rover at the
// site origin facing north), so the truth is the rendered range along each left pixel's ray.
struct RenderedPair {
  Scene scene;
  std::array<CahvorModel, 2> cameras;  // Rover (= site) frame.
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
  RenderedPair(int size, double azimuth) : scene(Options()) {
    RenderOptions render;
    render.near_posting_m = 0.04;  // Coarser than the generator's 2 cm / 8 cm: a fast unit
    render.mid_posting_m = 0.16;   // test (the truth is the same mesh's rendered range).
    render.far_radius_m = 50.0;
    const SiteMesh mesh(scene, {0.0, 0.0, scene.GroundHeightAt(0.0, 0.0)}, render);
    Eigen::Matrix3d enu_from_rover;  // Facing north: x -> north, y -> east, z -> down.
    enu_from_rover << 0, 1, 0, 1, 0, 0, 0, 0, -1;
    const Rigid3d enu_from_rover_pose(enu_from_rover,
                                      Eigen::Vector3d(0, 0, scene.GroundHeightAt(0.0, 0.0)));
    StereoCameraOptions head;
    head.width = head.height = size;
    head.field_of_view_deg = 45.0;
    cameras = StereoCameras(head, {azimuth, RadFromDeg(-15.0)});
    for (int i = 0; i < 2; ++i) {
      images[i] = mesh.Render(cameras[i].Transformed(enu_from_rover_pose), size, size,
                              21u + static_cast<uint32_t>(i));
    }
  }
  CameraFile File(int i) const {
    CameraFile file;
    file.model = cameras[i];
    file.frame = "ROVER_FRAME";
    file.site_from_frame = Rigid3d();
    file.site = 0;
    file.source = i == 0 ? "left" : "right";
    return file;
  }
};

const RenderedPair& Pair() {
  static const RenderedPair pair(512, RadFromDeg(15.0));
  return pair;
}

TEST(Rectification, RowsAreEpipolarAndMapsInvertTheModels) {
  const RenderedPair& f = Pair();
  const StereoRectification rect =
      RectifyStereoPair(f.cameras[0], f.cameras[1], {512, 512}, RectificationOptions{});
  EXPECT_NEAR(rect.baseline_m, 0.20, 1e-12);
  EXPECT_GT(rect.overlap_fraction, 0.8);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p =
        f.cameras[0].c + 8.0 * f.cameras[0].a + 3.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const auto l = rect.left.Project(p), r = rect.right.Project(p);
    ASSERT_TRUE(l && r);
    EXPECT_NEAR(l->y(), r->y(), 1e-9);  // Same row.
    EXPECT_GT(l->x() - r->x(), 0.0);    // Positive disparity in front.
    // The map sends the rectified pixel to where the original model sees the point (up to the
    // float maps and the model's radial distortion between pixel centres).
    const int x = static_cast<int>(std::lround(l->x())), y = static_cast<int>(std::lround(l->y()));
    if (x < 0 || y < 0 || x >= 512 || y >= 512 || rect.left_map_x.at<float>(y, x) < 0) continue;
    const Eigen::Vector3d on_ray = rect.left.c + 10.0 * rect.left.Unproject(Eigen::Vector2d(x, y));
    const Eigen::Vector2d original = *f.cameras[0].Project(on_ray);
    EXPECT_NEAR(rect.left_map_x.at<float>(y, x), original.x(), 1e-3);
    EXPECT_NEAR(rect.left_map_y.at<float>(y, x), original.y(), 1e-3);
  }
}

// A rectification built with a wrong relative orientation (the right camera turned 1 degree, the
// baseline tilted 3 degrees: what an error in a real calibration does); correspondences of
// points 2-40 m away as the true cameras see them on that rectified grid. The fit must undo the
// wrong correction and bring them to one row.
TEST(Rectification, RelativeOrientationFitUndoesAWrongCalibration) {
  const RenderedPair& f = Pair();
  const Eigen::Vector3d baseline = f.cameras[1].c - f.cameras[0].c;
  const Eigen::Vector3d axis = f.cameras[0].a;
  RectificationOptions options;
  options.correction.right_rotation =
      Eigen::AngleAxisd(RadFromDeg(1.0), (0.6 * baseline.normalized() + 0.8 * axis).normalized())
          .toRotationMatrix();
  options.correction.baseline_rotation =
      Eigen::AngleAxisd(RadFromDeg(3.0), axis.cross(baseline).normalized()).toRotationMatrix() *
      Eigen::AngleAxisd(RadFromDeg(1.0), axis).toRotationMatrix();
  const StereoRectification rect =
      RectifyStereoPair(f.cameras[0], f.cameras[1], {512, 512}, options);
  std::mt19937 random(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> pairs;
  double rms_wrong = 0.0;
  while (pairs.size() < 400) {
    const Eigen::Vector2d pixel(511.0 * unit(random), 511.0 * unit(random));
    const Eigen::Vector3d point =
        rect.left.c + (2.0 + 38.0 * unit(random)) * rect.left.Unproject(pixel);
    // Where the true right camera sees the point, on the grid rectified with the correction.
    const auto right = rect.right.Project(Eigen::Vector3d(
        rect.right.c + options.correction.right_rotation * (point - f.cameras[1].c)));
    if (!right) continue;
    pairs.emplace_back(pixel, *right);
    rms_wrong += std::pow(right->y() - pixel.y(), 2);
  }
  rms_wrong = std::sqrt(rms_wrong / 400.0);
  const RectificationFit fit = EstimateRectificationCorrection(rect, options.correction, pairs);
  EXPECT_GT(rms_wrong, 5.0);  // The wrong calibration matters.
  EXPECT_NEAR(fit.rms_before_px, rms_wrong, 1e-6);
  EXPECT_EQ(fit.inliers, 400u);
  EXPECT_LT(fit.rms_after_px, 0.02);
  // What may remain is what rows cannot see: the right camera turned about the vertical (a
  // range bias, not a row error), which trades against a forward tilt of the baseline.
  const Eigen::Vector3d x = baseline.normalized();
  const Eigen::Vector3d forward = (axis - axis.dot(x) * x).normalized();
  const Eigen::Vector3d down = forward.cross(x);
  const Eigen::AngleAxisd right_rest(fit.correction.right_rotation);
  const Eigen::Vector3d rest = right_rest.angle() * right_rest.axis();
  EXPECT_LT(std::abs(rest.dot(x)), RadFromDeg(0.01));
  EXPECT_LT(std::abs(rest.dot(forward)), RadFromDeg(0.01));
  const Eigen::Vector3d b = (fit.correction.baseline_rotation * baseline).normalized();
  EXPECT_LT(std::abs(b.dot(down)), RadFromDeg(0.01));  // Vertical tilt: undone.
  EXPECT_LT(std::acos(b.dot(x)), RadFromDeg(0.2));
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> few(pairs.begin(), pairs.begin() + 19);
  EXPECT_THROW(EstimateRectificationCorrection(rect, options.correction, few), Error);
}

TEST(DenseStereo, PointsMatchTheRenderedTruthWithinTheRangeErrorModel) {
  const RenderedPair& f = Pair();
  DenseStereoOptions options;
  const DenseStereoResult result =
      RunDenseStereo(f.images[0].dn, f.images[1].dn, f.File(0), f.File(1), options);
  EXPECT_EQ(result.cloud.frame, "SITE_FRAME");
  EXPECT_EQ(result.cloud.site, 0);
  ASSERT_GT(result.summary.points, 50000u);
  // Synthetic cameras are exact: tracked corners show no vertical disparity beyond tracking
  // noise, so no row correction is applied.
  EXPECT_LT(result.disparity.row_shift_before_rms_px, 0.5);
  EXPECT_TRUE(result.disparity.row_shift.empty());
  // Range error per bin over sigma_r (eq. 4.3, sigma_p = 0.5 px).
  const double b = result.summary.baseline_m, focal = result.summary.focal_px;
  const std::array<double, 5> edges = {0.0, 5.0, 10.0, 15.0, 25.0};
  std::array<double, 4> sum{}, sum_sq{}, sum_sigma_sq{};
  std::array<int, 4> count{};
  const cv::Mat& truth = f.images[0].range;
  for (const StereoPoint& p : result.cloud.points) {
    const int x = static_cast<int>(std::lround(p.left_x));
    const int y = static_cast<int>(std::lround(p.left_y));
    if (x < 1 || y < 1 || x >= truth.cols - 1 || y >= truth.rows - 1) continue;
    cv::Mat patch = truth(cv::Rect(x - 1, y - 1, 3, 3));
    double lo = 0, hi = 0;
    cv::minMaxLoc(patch, &lo, &hi);
    // Skip occlusion edges (grazing ground changes range by a few % per pixel at 20 m).
    if (!std::isfinite(lo) || !std::isfinite(hi) || hi - lo > 0.1 * lo) continue;
    const Eigen::Vector3d ray = f.cameras[0].Unproject(Eigen::Vector2d(p.left_x, p.left_y));
    cv::Mat sample;  // Bilinear truth at the point's own pixel.
    cv::getRectSubPix(truth, cv::Size(1, 1), cv::Point2f(p.left_x, p.left_y), sample, CV_32F);
    const double truth_range = sample.at<float>(0, 0);
    const double range = (p.position - f.cameras[0].c).dot(ray);
    for (int bin = 0; bin < 4; ++bin) {
      if (truth_range >= edges[bin] && truth_range < edges[bin + 1]) {
        const double sigma = truth_range * truth_range * 0.5 / (b * focal);
        sum[bin] += range - truth_range;
        sum_sq[bin] += (range - truth_range) * (range - truth_range);
        sum_sigma_sq[bin] += sigma * sigma;
        ++count[bin];
      }
    }
    // The covariance is eq. 4.3 along the line of sight.
    const Eigen::Vector3d los = (p.position - result.cloud.camera_center).normalized();
    const double r = (p.position - result.cloud.camera_center).norm();
    EXPECT_NEAR(std::sqrt(los.dot(p.covariance * los)), r * r * 0.5 / (b * focal), 1e-9);
  }
  for (int bin = 0; bin < 4; ++bin) {
    const double rms = std::sqrt(sum_sq[bin] / std::max(1, count[bin]));
    const double sigma = std::sqrt(sum_sigma_sq[bin] / std::max(1, count[bin]));
    ::testing::Test::RecordProperty("bin_" + std::to_string(bin) + "_points",
                                    std::to_string(count[bin]));
    ::testing::Test::RecordProperty("bin_" + std::to_string(bin) + "_rms_over_sigma",
                                    std::to_string(rms / sigma));
    const double mean = sum[bin] / std::max(1, count[bin]);
    std::printf(
        "range %4.0f-%4.0f m: %7d points, mean range error %+.4f m, RMS %.4f m, sigma_r %.4f m, "
        "ratio %.2f\n",
        edges[bin], edges[bin + 1], count[bin], mean, rms, sigma, rms / sigma);
    ASSERT_GT(count[bin], 300) << "bin " << bin;
    // No systematic range error: within 0.2 sigma_r (0.1 px of disparity). SGBM_3WAY's one-sided
    // smoothness alone gave +0.4 sigma_r at 0-5 m before the turned right run was averaged in.
    EXPECT_LT(std::abs(mean), 0.2 * sigma)
        << "range bin " << edges[bin] << "-" << edges[bin + 1] << " m";
    EXPECT_LT(rms, 1.5 * sigma) << "range bin " << edges[bin] << "-" << edges[bin + 1] << " m";
  }
  for (const StereoPoint& p : result.cloud.points) {
    ASSERT_LE((p.position - result.cloud.camera_center).norm(), options.max_range_m + 1e-9);
  }
}

TEST(DenseStereo, BadPairsAreRejectedWithClearErrors) {
  const RenderedPair& f = Pair();
  const DenseStereoOptions options;
  cv::Mat smaller;
  cv::resize(f.images[1].dn, smaller, cv::Size(256, 256));
  std::string message = testing::ErrorMessageOf(
      [&] { RunDenseStereo(f.images[0].dn, smaller, f.File(0), f.File(1), options); });
  EXPECT_NE(message.find("image sizes differ: 512x512 (left) vs 256x256 (right)"),
            std::string::npos)
      << message;

  CameraFile away = f.File(1);  // The right camera turned 90 degrees: no common view.
  const Rigid3d turn(Eigen::Matrix3d(Eigen::AngleAxisd(RadFromDeg(90.0), Eigen::Vector3d::UnitZ())),
                     Eigen::Vector3d::Zero());
  const Eigen::Vector3d c = f.cameras[1].c;
  away.model =
      CameraModel(f.cameras[1].Transformed(Rigid3d(Eigen::Quaterniond::Identity(), c) * turn *
                                           Rigid3d(Eigen::Quaterniond::Identity(), -c)));
  message = testing::ErrorMessageOf(
      [&] { RunDenseStereo(f.images[0].dn, f.images[1].dn, f.File(0), away, options); });
  EXPECT_NE(message.find("overlap"), std::string::npos) << message;

  message = testing::ErrorMessageOf(
      [&] { RunDenseStereo(f.images[1].dn, f.images[0].dn, f.File(1), f.File(0), options); });
  EXPECT_NE(message.find("are the images swapped?"), std::string::npos) << message;

  CameraFile other_frame = f.File(1);
  other_frame.frame = "SITE_FRAME";
  message = testing::ErrorMessageOf(
      [&] { RunDenseStereo(f.images[0].dn, f.images[1].dn, f.File(0), other_frame, options); });
  EXPECT_NE(message.find("different frames"), std::string::npos) << message;

  DenseStereoOptions bad = options;
  bad.block_size = 4;
  message = testing::ErrorMessageOf(
      [&] { RunDenseStereo(f.images[0].dn, f.images[1].dn, f.File(0), f.File(1), bad); });
  EXPECT_NE(message.find("DenseStereoOptions.block_size"), std::string::npos) << message;
}

// Asked to stop, stereo stops at its next stage and says which operation was cancelled.
TEST(DenseStereo, CancelNamesTheStage) {
  const RenderedPair& f = Pair();
  int calls = 0;
  const ProgressCallback stop_at_match = [&](double, std::string_view stage) {
    ++calls;
    return stage != "stereo: match";
  };
  const std::string message = testing::ErrorMessageOf([&] {
    RunDenseStereo(f.images[0].dn, f.images[1].dn, f.File(0), f.File(1), DenseStereoOptions{},
                   stop_at_match);
  });
  EXPECT_EQ(calls, 2);
  EXPECT_NE(message.find("cancelled during stereo: match"), std::string::npos) << message;
}

}  // namespace
}  // namespace areomap

namespace areomap {
namespace {

// The real K10 pair (NASA Ames, rocks on pavement; ASP .tsai cameras), at half resolution.
TEST(DenseStereoK10, PavementIsAPlaneWithinTheErrorModelAndRocksStandAboveIt) {
  SKIP_WITHOUT_SHARED_DATA();
  const auto dir = testing::SharedDataDir() / "k10";
  const CameraFile left = ReadCameraFile(dir / "black_left.tsai");
  const CameraFile right = ReadCameraFile(dir / "black_right.tsai");
  cv::Mat left_image, right_image;
  cv::resize(ReadImage(dir / "left4.png"), left_image, cv::Size(512, 384), 0, 0, cv::INTER_AREA);
  cv::resize(ReadImage(dir / "right4.png"), right_image, cv::Size(512, 384), 0, 0, cv::INTER_AREA);
  // Half-size images: the same cameras with half the focal length and principal point.
  const auto half = [](const CameraFile& file) {
    CameraFile out = file;
    PinholeModel m = std::get<PinholeModel>(file.model.variant());
    m.pitch = 2.0;
    m.cu -= 0.5;  // Pixel centres: full-size (0, 0) and (1, 1) average to half-size (0, 0).
    m.cv -= 0.5;
    out.model = m;
    return out;
  };
  DenseStereoOptions options;
  options.min_range_m = 0.6;
  options.block_size = 7;
  const DenseStereoResult result =
      RunDenseStereo(left_image, right_image, half(left), half(right), options);
  ::testing::Test::RecordProperty("valid_fraction", std::to_string(result.summary.valid_fraction));
  std::printf("K10 half size: %.1f%% of the overlap valid, %zu points\n",
              100.0 * result.summary.valid_fraction, result.summary.points);
  EXPECT_GT(result.summary.valid_fraction, 0.7);
  // The .tsai centres put the baseline a few degrees off: the vertical disparity grows with
  // the horizontal one until the relative-orientation fit takes it out.
  const DisparityResult& d = result.disparity;
  std::printf(
      "relative orientation: %zu corners, %.2f -> %.2f px, baseline %.2f deg, right %.2f deg\n",
      d.orientation_features, d.orientation_rms_before_px, d.orientation_rms_after_px,
      d.baseline_tilt_deg, d.right_rotation_deg);
  EXPECT_GT(d.orientation_features, 100u);
  EXPECT_GT(d.orientation_rms_before_px, 0.5);
  EXPECT_LT(d.orientation_rms_after_px, 0.5 * d.orientation_rms_before_px);
  const testing::K10Pavement k10 = testing::EvaluateK10Pavement(result.cloud, 2.0);
  std::printf(
      "pavement plane: %zu points, robust RMS %.4f m, error model %.4f m (ratio %.2f), "
      "normal %.3f %.3f %.3f\n",
      k10.pavement_points, k10.robust_rms_m, k10.model_rms_m, k10.robust_rms_m / k10.model_rms_m,
      k10.normal.x(), k10.normal.y(), k10.normal.z());
  ::testing::Test::RecordProperty("plane_rms_over_model",
                                  std::to_string(k10.robust_rms_m / k10.model_rms_m));
  ASSERT_GT(k10.pavement_points, 2000u);
  EXPECT_LT(k10.robust_rms_m, 2.0 * k10.model_rms_m);
  EXPECT_GT(k10.robust_rms_m, 0.25 * k10.model_rms_m);
  // The near rock (about 0.4 m tall) stands above the plane; its top is well clear of the noise.
  ASSERT_GT(k10.rock_points, 500u);
  std::printf("near rock: %zu points, 95th percentile height above the plane %.3f m\n",
              k10.rock_points, k10.rock_top_m);
  EXPECT_GT(k10.rock_top_m, 0.2);
  EXPECT_GT(k10.rock_top_m, 5.0 * k10.robust_rms_m);
  // The rover's own deck and wheels (rows > 600), nearer than the searched 0.6 m, match wrongly
  // and come back metres under the pavement; the line-of-sight check (line_of_sight.h) drops
  // them.
  const LineOfSightDrops& drops = result.summary.line_of_sight;
  std::printf("under the pavement: %zu points; dropped %zu buried, %zu floating\n",
              k10.underground_points, drops.buried, drops.floating);
  EXPECT_LE(k10.underground_points, 5u);
  EXPECT_LT(drops.buried + drops.floating, result.summary.points / 50);
}

}  // namespace
}  // namespace areomap
