// Stereo benchmark: areomap's dense stereo end to end (rectification, row check, SGBM in both
// directions, left-right check, triangulation with covariances) against a single plain OpenCV
// StereoSGBM run on the same rectified 8-bit pair with the same parameters, in this process.
// Also reports the point accuracy per range bin against the rendered truth (eq. 4.3 sigma_r).
//
// Scene: the generator's Navcam (1024 x 1024, 45 deg, 20 cm baseline, 1.5 m mast) rendering
// of a 60 m terrain with rocks, 20 degrees down, as in `areomap simulate --preset demo`.
//
// Run: build/release/bench/areomap_bench_stereo [repetitions, default 5]
//
// With `--demo DIR` (a mission from `areomap simulate --preset demo --out DIR`) it instead runs
// the stereo on the mission's own files (images and labels, as `areomap stereo` reads them) for
// pairs 0 and 5 of every site, and compares each sampled point's range along its pixel's ray with
// the range at which that ray meets the analytic scene (rebuilt from the demo preset), placed
// with the TRUE site pose (truth/sites.csv): the labels carry the telemetry heading.
// With `--k10 DIR` (../shared/data/k10) it runs the real K10 pair at full size (see RunK10).
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "../tests/map/k10_pavement.h"
#include "areomap/map/camera_models.h"
#include "areomap/map/dense_stereo.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/image_io.h"
#include "areomap/samples/mission.h"
#include "areomap/samples/rover.h"
#include "areomap/samples/scene.h"

namespace areomap {
namespace {

template <typename Function>
double MedianSeconds(int repetitions, Function function) {
  std::vector<double> times;
  for (int i = 0; i < repetitions; ++i) {
    const auto start = std::chrono::steady_clock::now();
    function();
    times.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

int Run(int repetitions) {
  SceneOptions scene_options;
  scene_options.half_extent_m = 60.0;
  scene_options.crater_count = 0;
  scene_options.roughness_m = 0.3;
  scene_options.rock_path = {{0.0, 0.0}, {0.0, 20.0}};
  scene_options.rock_corridor_m = 12.0;
  const Scene scene(scene_options);
  RenderOptions render;
  render.far_radius_m = 50.0;
  const SiteMesh mesh(scene, {0.0, 0.0, scene.GroundHeightAt(0.0, 0.0)}, render);
  Eigen::Matrix3d enu_from_rover;
  enu_from_rover << 0, 1, 0, 1, 0, 0, 0, 0, -1;
  const Rigid3d enu_from_rover_pose(enu_from_rover,
                                    Eigen::Vector3d(0, 0, scene.GroundHeightAt(0.0, 0.0)));
  const auto cameras = StereoCameras(StereoCameraOptions{}, {RadFromDeg(10.0), RadFromDeg(-20.0)});
  std::array<SiteMesh::Image, 2> images;
  std::array<CameraFile, 2> files;
  for (int i = 0; i < 2; ++i) {
    images[i] = mesh.Render(cameras[i].Transformed(enu_from_rover_pose), 1024, 1024, 7u + i);
    files[i].model = cameras[i];
    files[i].frame = "ROVER_FRAME";
    files[i].site_from_frame = Rigid3d();
    files[i].site = 0;
  }
  const DenseStereoOptions options;
  DenseStereoResult result;
  const double ours = MedianSeconds(repetitions, [&] {
    result = RunDenseStereo(images[0].dn, images[1].dn, files[0], files[1], options);
  });
  const DisparityResult& d = result.disparity;
  const int b = options.block_size;
  const double opencv = MedianSeconds(repetitions, [&] {
    const cv::Ptr<cv::StereoSGBM> sgbm =
        cv::StereoSGBM::create(d.min_disparity, d.num_disparities, b, 8 * b * b, 32 * b * b, -1, 63,
                               options.uniqueness_ratio, options.speckle_window_px,
                               options.speckle_range_px, cv::StereoSGBM::MODE_SGBM_3WAY);
    cv::Mat disparity;
    sgbm->compute(d.left8, d.right8, disparity);
  });
  std::printf(
      "stereo per 1024x1024 pair (median of %d): areomap end to end %.3f s, plain "
      "OpenCV SGBM on the rectified pair %.3f s, ratio %.2f\n",
      repetitions, ours, opencv, ours / opencv);
  std::printf("disparities [%d, %d), %zu points, %.1f%% of the overlap valid\n", d.min_disparity,
              d.min_disparity + d.num_disparities, result.summary.points,
              100.0 * result.summary.valid_fraction);

  // Accuracy per range bin: range along the left pixel's ray vs the rendered range there.
  const std::array<double, 5> edges = {0.0, 5.0, 10.0, 15.0, 25.0};
  std::array<std::vector<double>, 4> errors;
  std::array<double, 4> sigma_sq{};
  const cv::Mat& truth = images[0].range;
  for (const StereoPoint& p : result.cloud.points) {
    const int x = static_cast<int>(std::lround(p.left_x)),
              y = static_cast<int>(std::lround(p.left_y));
    if (x < 1 || y < 1 || x >= truth.cols - 1 || y >= truth.rows - 1) continue;
    double lo = 0, hi = 0;
    cv::minMaxLoc(truth(cv::Rect(x - 1, y - 1, 3, 3)), &lo, &hi);
    if (!std::isfinite(lo) || !std::isfinite(hi) || hi - lo > 0.1 * lo) continue;
    cv::Mat sample;
    cv::getRectSubPix(truth, cv::Size(1, 1), cv::Point2f(p.left_x, p.left_y), sample, CV_32F);
    const double r_true = sample.at<float>(0, 0);
    const Eigen::Vector3d ray = cameras[0].Unproject(Eigen::Vector2d(p.left_x, p.left_y));
    const double r = (p.position - cameras[0].c).dot(ray);
    for (int bin = 0; bin < 4; ++bin) {
      if (r_true >= edges[bin] && r_true < edges[bin + 1]) {
        errors[bin].push_back(r - r_true);
        const double s = StereoRangeSigma(r_true, result.summary.baseline_m,
                                          result.summary.focal_px, options.parallax_sigma_px);
        sigma_sq[bin] += s * s;
      }
    }
  }
  std::printf(
      "| range bin | points | mean error | RMS error | sigma_r (eq. 4.3) | RMS / sigma_r |\n");
  std::printf("|---|---:|---:|---:|---:|---:|\n");
  for (int bin = 0; bin < 4; ++bin) {
    const auto& e = errors[bin];
    double sum = 0.0, sum_sq = 0.0;
    for (double v : e) {
      sum += v;
      sum_sq += v * v;
    }
    const double n = std::max<double>(1.0, static_cast<double>(e.size()));
    const double rms = std::sqrt(sum_sq / n), sigma = std::sqrt(sigma_sq[bin] / n);
    std::printf("| %.0f-%.0f m | %zu | %+.4f m | %.4f m | %.4f m | %.2f |\n", edges[bin],
                edges[bin + 1], e.size(), sum / n, rms, sigma, rms / sigma);
  }
  return 0;
}

// The range at which `origin + t direction` (ENU, direction unit) first meets the scene's
// surface, by marching in 1% steps and bisecting; NaN if not within 60 m.
double RayHitRange(const Scene& scene, const Eigen::Vector3d& origin,
                   const Eigen::Vector3d& direction) {
  const auto above = [&](double t) {
    const Eigen::Vector3d p = origin + t * direction;
    return p.z() - scene.HeightAt(p.x(), p.y());
  };
  double t0 = 0.3, f0 = above(t0);
  if (f0 <= 0.0) return std::nan("");
  while (t0 < 60.0) {
    const double t1 = t0 * 1.01 + 0.005, f1 = above(t1);
    if (f1 <= 0.0) {
      double lo = t0, hi = t1;
      for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        (above(mid) > 0.0 ? lo : hi) = mid;
      }
      return 0.5 * (lo + hi);
    }
    t0 = t1;
    f0 = f1;
  }
  return std::nan("");
}

int RunDemo(const std::filesystem::path& dir) {
  const MissionOptions mission = MissionOptions::Preset("demo");
  const Scene scene(mission.scene);
  std::map<int, Eigen::Vector3d> truth;  // site -> (north, east, heading [rad])
  {
    std::ifstream in(dir / "truth" / "sites.csv");
    std::string line;
    std::getline(in, line);
    while (std::getline(in, line)) {
      std::replace(line.begin(), line.end(), ',', ' ');
      std::istringstream row(line);
      int site = 0;
      double north = 0, east = 0, down = 0, heading = 0;
      row >> site >> north >> east >> down >> heading;
      truth[site] = Eigen::Vector3d(north, east, RadFromDeg(heading));
    }
  }
  const std::array<double, 5> edges = {0.0, 5.0, 10.0, 15.0, 25.0};
  std::array<std::vector<double>, 4> errors;
  std::array<double, 4> sigma_sq{};
  size_t overlap = 0, valid = 0, points = 0;
  const DenseStereoOptions options;
  for (const auto& [site, pose] : truth) {
    for (int pair : {0, 5}) {
      char stem[96];
      std::snprintf(stem, sizeof(stem), "sites/site_%03d/navcam_p%02d_", site, pair);
      const auto left_png = dir / (std::string(stem) + "left.png");
      const auto right_png = dir / (std::string(stem) + "right.png");
      if (!std::filesystem::exists(left_png)) continue;
      const CameraFile left = ReadCameraForImage(left_png), right = ReadCameraForImage(right_png);
      const DenseStereoResult result =
          RunDenseStereo(ReadImage(left_png), ReadImage(right_png), left, right, options);
      overlap += result.summary.overlap_pixels;
      valid += result.summary.valid_pixels;
      points += result.summary.points;
      // True pose: ENU (scene) from rover, as the generator rendered it.
      const Eigen::Vector3d site_in_enu(pose.y(), pose.x(),
                                        scene.GroundHeightAt(pose.y(), pose.x()));
      const Rigid3d enu_from_rover =
          Rigid3d(SiteFromEnu().rotation.conjugate(), site_in_enu) *
          Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(pose.z(), Eigen::Vector3d::UnitZ())),
                  Eigen::Vector3d::Zero());
      const Rigid3d rover_from_site = left.site_from_frame->Inverse();
      const CameraModel left_in_enu = left.model.Transformed(enu_from_rover);
      for (size_t i = 0; i < result.cloud.points.size(); i += 97) {
        const StereoPoint& p = result.cloud.points[i];
        const CameraRay ray = left_in_enu.Unproject(Eigen::Vector2d(p.left_x, p.left_y));
        const double r_true = RayHitRange(scene, ray.origin, ray.direction);
        if (!std::isfinite(r_true)) continue;
        const Eigen::Vector3d p_enu = enu_from_rover * (rover_from_site * p.position);
        const double r = (p_enu - ray.origin).dot(ray.direction);
        for (int bin = 0; bin < 4; ++bin) {
          if (r_true >= edges[bin] && r_true < edges[bin + 1]) {
            errors[bin].push_back(r - r_true);
            const double s = StereoRangeSigma(r_true, result.summary.baseline_m,
                                              result.summary.focal_px, options.parallax_sigma_px);
            sigma_sq[bin] += s * s;
          }
        }
      }
      std::fprintf(stderr, "site %d pair %d: %zu points\n", site, pair, result.summary.points);
    }
  }
  std::printf(
      "demo mission: %zu points, %.1f%% of the overlap valid; every 97th point checked\n", points,
      100.0 * static_cast<double>(valid) / static_cast<double>(std::max<size_t>(1, overlap)));
  std::printf(
      "| range bin | points | mean error | RMS error | robust sigma (1.4826 MAD) | sigma_r (eq. "
      "4.3) | RMS / sigma_r | robust / sigma_r | within 3 sigma_r |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|\n");
  for (int bin = 0; bin < 4; ++bin) {
    const auto& e = errors[bin];
    double sum = 0.0, sum_sq = 0.0;
    for (double v : e) sum += v, sum_sq += v * v;
    const double n = std::max<double>(1.0, static_cast<double>(e.size()));
    const double rms = std::sqrt(sum_sq / n), sigma = std::sqrt(sigma_sq[bin] / n);
    size_t inside = 0;
    for (double v : e) inside += std::abs(v) <= 3.0 * sigma ? 1 : 0;
    std::vector<double> deviations;
    std::vector<double> sorted = e;
    std::sort(sorted.begin(), sorted.end());
    const double median = sorted.empty() ? 0.0 : sorted[sorted.size() / 2];
    for (double v : e) deviations.push_back(std::abs(v - median));
    std::sort(deviations.begin(), deviations.end());
    const double robust = deviations.empty() ? 0.0 : 1.4826 * deviations[deviations.size() / 2];
    std::printf(
        "| %.0f-%.0f m | %zu | %+.4f m | %.4f m | %.4f m | %.4f m | %.2f | %.2f | %.1f%% |\n",
        edges[bin], edges[bin + 1], e.size(), sum / n, rms, robust, sigma, rms / sigma,
        robust / sigma, 100.0 * static_cast<double>(inside) / n);
  }
  return 0;
}

// --k10 DIR: the real K10 pair (DIR = ../shared/data/k10) at full size with the default options
// (nearest range 0.6 m): valid fraction of the overlap, the relative-orientation fit, the
// pavement plane against the error model and the near rock's height (tests/map/k10_pavement.h).
int RunK10(const std::filesystem::path& dir) {
  const CameraFile left = ReadCameraFile(dir / "black_left.tsai");
  const CameraFile right = ReadCameraFile(dir / "black_right.tsai");
  DenseStereoOptions options;
  options.min_range_m = 0.6;
  const auto start = std::chrono::steady_clock::now();
  const DenseStereoResult result = RunDenseStereo(
      ReadImage(dir / "left4.png"), ReadImage(dir / "right4.png"), left, right, options);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const DisparityResult& d = result.disparity;
  std::printf(
      "K10 full size (1024x768): %.1f%% of the overlap valid (%zu of %zu px), %zu points, %.2f s\n"
      "relative orientation: %zu corners, vertical disparity RMS %.2f -> %.2f px, right camera "
      "turned %.2f deg, baseline tilted %.2f deg; residual row field %.2f -> %.2f px\n",
      100.0 * result.summary.valid_fraction, result.summary.valid_pixels,
      result.summary.overlap_pixels, result.summary.points, seconds, d.orientation_features,
      d.orientation_rms_before_px, d.orientation_rms_after_px, d.right_rotation_deg,
      d.baseline_tilt_deg, d.row_shift_before_rms_px, d.row_shift_rms_px);
  const testing::K10Pavement k10 = testing::EvaluateK10Pavement(result.cloud, 1.0);
  std::printf(
      "pavement 1.5-4 m: %zu points, robust RMS %.4f m, error model %.4f m (ratio %.2f); near "
      "rock: %zu points, 95th percentile %.3f m above the plane\n",
      k10.pavement_points, k10.robust_rms_m, k10.model_rms_m, k10.robust_rms_m / k10.model_rms_m,
      k10.rock_points, k10.rock_top_m);
  return 0;
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  if (argc > 2 && std::string(argv[1]) == "--demo") return areomap::RunDemo(argv[2]);
  if (argc > 2 && std::string(argv[1]) == "--k10") return areomap::RunK10(argv[2]);
  return areomap::Run(argc > 1 ? std::max(1, std::atoi(argv[1])) : 5);
}
