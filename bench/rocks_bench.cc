// Rock landmark benchmark: peaks + surface points + models for one ~500 k point site, and one
// site pair matched, with a brute-force neighbour-search baseline in the same process.
//
// The baseline finds the same window maxima (50 x 50 cm, > 10 cm relief, >= 3 points) by
// scanning every point for every point, O(n^2); it runs on a sub-cloud (the points within
// `baseline_radius` of a spot near the camera, where the cloud is densest) and its time is
// compared with ExtractRocks's peak stage on the same sub-cloud, and extrapolated (x n^2) to
// the full cloud.
//
// Run: build/release/bench/areomap_bench_rocks
#include <chrono>
#include <cmath>
#include <cstdio>
#include <vector>

#include <tbb/global_control.h>

#include "areomap/registration/rock_extraction.h"
#include "areomap/registration/rock_matching.h"
#include "areomap/samples/simulated_points.h"

namespace areomap {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

Scene BenchScene() {
  SceneOptions options;
  options.half_extent_m = 80.0;
  options.crater_count = 2;
  options.roughness_m = 0.3;
  options.rock_path = {Eigen::Vector2d(-40, 0), Eigen::Vector2d(40, 0)};
  options.rock_abundance_k = 0.08;
  options.rock_corridor_m = 30.0;
  options.seed = 5;
  return Scene(options);
}

// Brute force: a point is a peak when no point of its 50 x 50 cm window is higher, the window
// spans > 10 cm of elevation and holds >= 3 points.
int BruteForcePeaks(const PointCloud& cloud, const RockExtractionOptions& options) {
  const double half = 0.5 * options.peak_window_m;
  int peaks = 0;
  for (const StereoPoint& p : cloud.points) {
    double low = -p.position.z();
    int count = 0;
    bool highest = true;
    for (const StereoPoint& q : cloud.points) {
      if (std::abs(q.position.x() - p.position.x()) > half ||
          std::abs(q.position.y() - p.position.y()) > half) {
        continue;
      }
      ++count;
      low = std::min(low, -q.position.z());
      if (-q.position.z() > -p.position.z()) {
        highest = false;
        break;
      }
    }
    if (highest && count >= options.min_window_points &&
        -p.position.z() - low > options.min_peak_relief_m) {
      ++peaks;
    }
  }
  return peaks;
}

}  // namespace
}  // namespace areomap

int main() {
  using namespace areomap;
  const Scene scene = BenchScene();
  SimulatedPointsOptions sim;
  sim.angular_step_rad = 2.4e-3;
  sim.max_range_m = 30.0;
  const PointCloud cloud = SimulateSitePointCloud(scene, {-8.0, 0.0}, 1, sim);
  std::printf("site cloud: %zu points (full panorama, 2-30 m)\n", cloud.points.size());

  RockExtractionOptions options;
  for (int threads : {1, 2}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    RockExtractionSummary summary;
    auto start = Clock::now();
    const std::vector<ExtractedRock> rocks = ExtractRocks(cloud, options, &summary);
    const double all = Seconds(start);
    RockExtractionOptions peaks_only = options;
    peaks_only.fit_models = false;
    start = Clock::now();
    ExtractRocks(cloud, peaks_only);
    const double no_models = Seconds(start);
    std::printf(
        "%d thread(s): ExtractRocks %.3f s (peaks + surfaces %.3f s, models %.3f s): %d "
        "candidates, %d rocks, %d modeled\n",
        threads, all, no_models, all - no_models, summary.peak_candidates, summary.rocks,
        summary.modeled);
  }

  // Baseline on a sub-cloud.
  PointCloud sub;
  sub.camera_center = cloud.camera_center;
  const Eigen::Vector2d spot(4.0, 2.0);
  for (const StereoPoint& p : cloud.points) {
    if ((p.position.head<2>() - spot).norm() < 3.0) sub.points.push_back(p);
  }
  RockExtractionOptions peaks_only = options;
  peaks_only.fit_models = false;
  RockExtractionSummary sub_summary;
  auto start = Clock::now();
  ExtractRocks(sub, peaks_only, &sub_summary);
  const double grid_time = Seconds(start);
  start = Clock::now();
  const int brute_peaks = BruteForcePeaks(sub, options);
  const double brute_time = Seconds(start);
  const double scale = std::pow(
      static_cast<double>(cloud.points.size()) / static_cast<double>(sub.points.size()), 2);
  std::printf(
      "sub-cloud %zu points: grid peaks+surfaces %.4f s (%d window maxima); brute-force window "
      "maxima %.3f s (%d): ratio %.1fx; brute force extrapolated to the full cloud: %.0f s\n",
      sub.points.size(), grid_time, sub_summary.peak_candidates, brute_time, brute_peaks,
      brute_time / grid_time, brute_time * scale);

  // One pair: the site above and one 15 m east of it.
  const PointCloud cloud_b = SimulateSitePointCloud(scene, {7.0, 0.0}, 2, sim);
  SiteRocks a, b;
  a.site = 1;
  a.camera_center = cloud.camera_center;
  a.rocks = ExtractRocks(cloud, options);
  b.site = 2;
  b.camera_center = cloud_b.camera_center;
  b.rocks = ExtractRocks(cloud_b, options);
  const Rigid3d prior(Eigen::Matrix3d::Identity(),
                      Eigen::Vector3d(0.3, 15.0 - 0.4,
                                      -(scene.GroundHeightAt(7, 0) - scene.GroundHeightAt(-8, 0))));
  constexpr int kRuns = 20;
  start = Clock::now();
  SitePairMatch match;
  for (int k = 0; k < kRuns; ++k) match = MatchSitePair(a, b, prior, {});
  const double pair_time = Seconds(start) / kRuns;
  std::printf("pair 15 m: %zu + %zu rocks, MatchSitePair %.4f s, %zu tie points, %s\n",
              a.rocks.size(), b.rocks.size(), pair_time, match.tie_points.size(),
              ToString(match.report.outcome).c_str());
  return 0;
}
