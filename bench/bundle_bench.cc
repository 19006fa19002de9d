// Bundle adjustment timings on the generator's long traverse (46 sites, ~1.1 km, 10 % odometry
// noise, 8 stereo tie points per leg, 2 orbital control points per site), each against a
// baseline run in the same process on the same input, with the ratio printed:
//   full adjustment (sparse Schur, Schur-complement covariance)
//     vs the dense Schur linear solver, and vs ceres::Covariance (sparse QR) for the covariance;
//   one incremental step (add the last site, adjust a window of 5 sites) vs a full
//     re-adjustment after adding it.
// Times are wall-clock medians of `--repeats` runs (default 5), single-threaded.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "areomap/adjustment/bundle_adjustment.h"
#include "areomap/adjustment/traverse_anchoring.h"
#include "bundle_simulation.h"

namespace areomap {
namespace {

double MedianSeconds(int repeats, const std::function<void()>& setup,
                     const std::function<void()>& work) {
  std::vector<double> times;
  for (int i = 0; i < repeats; ++i) {
    setup();
    const auto start = std::chrono::steady_clock::now();
    work();
    times.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

testing::SimulatedNetworkOptions LongTraverse(int site_count) {
  testing::SimulatedNetworkOptions options;
  options.telemetry.scale_sigma = 0.10;
  options.control_points_per_site = 2;
  options.traverse.site_count = site_count;
  options.half_extent_m = 700.0 * std::max(1.0, std::sqrt(site_count / 46.0));
  return options;
}

void Row(const char* name, double seconds, const char* baseline, double baseline_seconds) {
  std::printf("| %s | %.1f ms | %s | %.1f ms | %.3fx |\n", name, 1e3 * seconds, baseline,
              1e3 * baseline_seconds, seconds / baseline_seconds);
}

void Run(int repeats) {
  for (int sites : {46, 184}) {
    const testing::SimulatedNetwork net = testing::SimulateNetwork(LongTraverse(sites));
    std::printf("\n%d sites, %.0f m, %zu tie points, %zu control points, %zu priors\n\n", sites,
                net.length_m, net.input.tie_points.size(), net.input.control_points.size(),
                net.input.priors.size());
    std::printf("| case | time | baseline | baseline time | ratio |\n|---|---:|---|---:|---:|\n");
    BundleResult result;
    const auto nothing = [] {};
    const double full = MedianSeconds(repeats, nothing, [&] { result = AdjustBundle(net.input); });
    BundleOptions dense;
    dense.dense_schur = true;
    const double full_dense =
        MedianSeconds(repeats, nothing, [&] { AdjustBundle(net.input, dense); });
    BundleOptions ceres_covariance;
    ceres_covariance.ceres_covariance = true;
    BundleResult reference;
    const double full_ceres_cov = MedianSeconds(
        repeats, nothing, [&] { reference = AdjustBundle(net.input, ceres_covariance); });
    Row("full adjustment (sparse Schur + Schur covariance)", full, "dense Schur solver",
        full_dense);
    Row("full adjustment (sparse Schur + Schur covariance)", full, "ceres::Covariance (sparse QR)",
        full_ceres_cov);
    std::printf(
        "| of which covariance (Schur complement) | %.1f ms | ceres::Covariance | %.1f ms | "
        "%.3fx |\n",
        1e3 * result.covariance_seconds, 1e3 * reference.covariance_seconds,
        result.covariance_seconds / reference.covariance_seconds);

    // Incremental: every site but the last already adjusted; add it and adjust a window.
    IncrementalBundle before(net.input.body, net.input.origin);
    for (int s = 0; s + 1 < net.input.site_count; ++s) {
      const testing::SiteLinks links = testing::LinksOfSite(net.input, s);
      before.AddSite(net.telemetry[static_cast<size_t>(s)], links.priors, links.tie_points,
                     links.control_points);
    }
    before.Full();
    const int last = net.input.site_count - 1;
    const testing::SiteLinks links = testing::LinksOfSite(net.input, last);
    IncrementalBundle step = before;
    const auto add_last = [&] {
      step = before;
      step.AddSite(step.input().initial_poses.back() * links.priors.front().a_from_b, links.priors,
                   links.tie_points, links.control_points);
    };
    BundleResult window_result;
    const double incremental =
        MedianSeconds(repeats, add_last, [&] { window_result = step.AdjustWindow(5); });
    const double full_after_add = MedianSeconds(repeats, add_last, [&] { step.Full(); });
    Row("incremental step (add a site, window of 5)", incremental, "full re-adjustment",
        full_after_add);
    const AnchoredTraverse anchored = AnchorTraverse(net.input, result, [&] {
      std::vector<Eigen::Vector3d> truth;
      for (const Rigid3d& t : net.truth) truth.push_back(t.translation);
      return truth;
    }());
    double worst = 0.0;
    for (const AnchoredSite& s : anchored.sites) worst = std::max(worst, s.adjusted_error_m);
    std::printf(
        "\ncheck: sigma0 %.3f, largest horizontal error %.3f m, covariance difference "
        "Schur vs Ceres %.2e (relative)\n",
        result.sigma0, worst,
        (result.pose_covariance - reference.pose_covariance).norm() /
            reference.pose_covariance.norm());
  }
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  int repeats = 5;
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "--repeats") == 0) repeats = std::max(1, std::atoi(argv[i + 1]));
  }
  areomap::Run(repeats);
  return 0;
}
