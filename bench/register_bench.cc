// Orbital registration benchmark: one rover orthophoto registered onto a HiRISE-like orbital
// image (generated: tests/registration/orbital_trial.h) by MatchOrthoToOrbital (resampling,
// masked FFT NCC coarse to fine, subpixel, confidence), against OpenCV cv::matchTemplate
// (TM_CCOEFF_NORMED) brute force at full resolution over the same search window, on the same
// resampled template, in this process. Both must find the same shift (to 1 px). The methods run
// in turn, round after round; the times are medians over the rounds, the ratios the median of
// the rounds' ratios.
//
// Run: build/release/bench/areomap_bench_register [repetitions] [largest search radius, px]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_match.h"
#include "areomap/registration/orbital_template.h"
#include "orbital_trial.h"

namespace areomap {
namespace {

double SecondsOf(const std::function<void()>& run) {
  const auto t0 = std::chrono::steady_clock::now();
  run();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// One round of the benchmark: each method once [s]; theirs[use_mask].
struct Round {
  double ours = 0.0, resample = 0.0;
  double theirs[2] = {0.0, 0.0};
};

double Median(const std::vector<Round>& rounds, const std::function<double(const Round&)>& of) {
  std::vector<double> values;
  for (const Round& r : rounds) values.push_back(of(r));
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

struct Baseline {
  cv::Point shift;  // Correction [orbital px].
  double value = 0.0;
};

// cv::matchTemplate over the shifts the registration searches: the orbital pixels those
// shifts reach, the template's invalid pixels filled with its mean (with `use_mask`, OpenCV's
// template mask instead).
Baseline MatchTemplateBaseline(const OrbitalMatch& m, int radius, bool use_mask) {
  const OrbitalTemplate& t = m.templ;
  const cv::Rect reach(t.col0 - radius - m.orbital_window.col0,
                       t.row0 - radius - m.orbital_window.row0, t.image.cols + 2 * radius,
                       t.image.rows + 2 * radius);
  const cv::Mat image =
      m.orbital_patch(reach & cv::Rect(0, 0, m.orbital_patch.cols, m.orbital_patch.rows));
  const cv::Scalar mean = cv::mean(t.image, t.mask);
  cv::Mat templ(t.image.size(), CV_32F, mean);
  t.image.copyTo(templ, t.mask);
  cv::Mat result;
  if (use_mask) {
    cv::Mat mask;
    t.mask.convertTo(mask, CV_32F, 1.0 / 255.0);
    cv::matchTemplate(image, templ, result, cv::TM_CCOEFF_NORMED, mask);
  } else {
    cv::matchTemplate(image, templ, result, cv::TM_CCOEFF_NORMED);
  }
  cv::patchNaNs(result, -2.0);
  double best = 0.0;
  cv::Point at;
  cv::minMaxLoc(result, nullptr, &best, nullptr, &at);
  return {{at.x - radius, at.y - radius}, best};
}

int Main(int argc, char** argv) {
  const int repetitions = argc > 1 ? std::max(1, std::atoi(argv[1])) : 5;
  // Cases whose search radius is over this are skipped (to profile the small windows alone).
  const int largest_radius = argc > 2 ? std::atoi(argv[2]) : std::numeric_limits<int>::max();
  std::printf("%-46s %6s %10s %10s %10s %8s %8s %s\n", "case", "search", "register", "matching",
              "baseline", "ratio", "ratio m.", "same answer");
  struct Case {
    double ortho_half_m, orbital_half_m, prior_sigma_m;
  };
  for (const Case& c : {Case{20.0, 60.0, 5.0}, Case{30.0, 100.0, 10.0}, Case{30.0, 150.0, 25.0},
                        Case{30.0, 250.0, 50.0}}) {
    testing::TrialOptions o;
    o.seed = 1001;
    o.ortho_half_extent_m = c.ortho_half_m;
    o.orbital_half_extent_m = c.orbital_half_m;
    o.telemetry_sigma_m = c.prior_sigma_m / 2.0;
    o.decoy = false;
    const double radius_estimate = 3.0 * c.prior_sigma_m / 0.25;
    if (radius_estimate > largest_radius + 1.0) continue;
    testing::Trial trial = testing::MakeTrial(o);
    trial.prior.sigma_m = c.prior_sigma_m;
    // One match first, for the search radius the baseline covers.
    OrbitalMatch match = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
    const int radius = match.search_radius_px;
    // The resampling alone (both methods need the template on the orbital grid).
    const PixelGrid ortho_grid(trial.ortho.geotransform, trial.ortho.crs_wkt, "ortho");
    const PixelGrid orbital_grid(trial.orbital->geotransform(), trial.orbital->crs_wkt(),
                                 "orbital");
    const Eigen::Vector2d rover = ortho_grid.GeographicToPixel(trial.prior.position);
    // Rounds of every method in turn: a shared machine's load changes from second to second, so
    // each round's ratio compares runs made under the same load; the median round is reported.
    std::vector<Round> rounds(repetitions);
    Baseline base[2];
    for (Round& round : rounds) {
      round.ours =
          SecondsOf([&] { match = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior); });
      round.resample =
          SecondsOf([&] { ResampleToOrbitalGrid(trial.ortho, ortho_grid, orbital_grid, rover); });
      for (const bool use_mask : {true, false}) {
        round.theirs[use_mask] =
            SecondsOf([&] { base[use_mask] = MatchTemplateBaseline(match, radius, use_mask); });
      }
    }
    const double ours = Median(rounds, [](const Round& r) { return r.ours; });
    const double resample = Median(rounds, [](const Round& r) { return r.resample; });
    for (const bool use_mask : {true, false}) {
      const double theirs = Median(rounds, [&](const Round& r) { return r.theirs[use_mask]; });
      const double ratio =
          Median(rounds, [&](const Round& r) { return r.theirs[use_mask] / r.ours; });
      const double matching_ratio = Median(
          rounds, [&](const Round& r) { return r.theirs[use_mask] / (r.ours - r.resample); });
      const Baseline& b = base[use_mask];
      const bool same = std::abs(b.shift.x - match.shift_px.x()) <= 1.0 &&
                        std::abs(b.shift.y - match.shift_px.y()) <= 1.0;
      char name[128];
      std::snprintf(name, sizeof(name), "%dx%d px template, matchTemplate%s",
                    match.templ.image.cols, match.templ.image.rows,
                    use_mask ? " + mask" : " (no mask)");
      std::printf(
          "%-46s %4d px %8.1f ms %8.1f ms %8.1f ms %7.1fx %7.1fx %s (ours %s %+.2f %+.2f "
          "px CC %.3f, OpenCV %+d %+d CC %.3f)\n",
          name, radius, 1e3 * ours, 1e3 * (ours - resample), 1e3 * theirs, ratio, matching_ratio,
          same ? "yes" : "NO", match.matched ? "match" : "no match", match.shift_px.x(),
          match.shift_px.y(), match.correlation, b.shift.x, b.shift.y, b.value);
    }
  }
  return 0;
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) { return areomap::Main(argc, argv); }
