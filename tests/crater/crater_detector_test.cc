#include "areomap/crater/crater_detector.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include "areomap/crater/crater_score.h"
#include "areomap/crater/ellipse_fit.h"
#include "areomap/map/error.h"
#include "crater_scene.h"
#include "test_support.h"

namespace areomap {
namespace {

using testing::CraterScene;
using testing::MakeCraterScene;

std::vector<CraterCircle> Circles(const std::vector<Ellipse>& ellipses) {
  std::vector<CraterCircle> out;
  for (const Ellipse& e : ellipses) out.push_back({e.center, e.semi_major + e.semi_minor});
  return out;
}

std::vector<CraterCircle> Circles(const std::vector<CraterDetection>& detections) {
  std::vector<CraterCircle> out;
  for (const CraterDetection& d : detections) out.push_back({d.ellipse.center, d.Diameter()});
  return out;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? std::numeric_limits<double>::quiet_NaN() : v[v.size() / 2];
}

// 1000 x 1000 px at 0.5 m/px: craters of 5-80 m are 10-160 px.
const CraterScene& FieldScene() {
  static const CraterScene scene = [] {
    SceneOptions s;
    s.half_extent_m = 250.0;
    s.crater_count = 30;
    s.crater_min_diameter_m = 5.0;
    s.crater_max_diameter_m = 80.0;
    s.seed = 7;
    OrbitalImageOptions o;
    o.gsd_m = 0.5;
    o.sun_azimuth_deg = 120.0;
    o.sun_elevation_deg = 30.0;
    return MakeCraterScene(s, o, 1.0);
  }();
  return scene;
}

TEST(DetectCraters, FindsGeneratedCratersWithSubPixelAccuracy) {
  const CraterScene& scene = FieldScene();
  CraterDetectorOptions options;
  options.sun_azimuth_deg = 120.0;
  const auto start = std::chrono::steady_clock::now();
  const std::vector<CraterDetection> found =
      DetectCraters(scene.products.image.bands[0], RimSource::kImage, options);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const CraterScore score =
      ScoreCraters(Circles(scene.truth_px), Circles(found), {10.0, 20.0, 40.0, 80.0, 1e9});
  std::vector<double> center_errors, axis_errors;
  for (const auto& [t, d] : score.matches) {
    const Ellipse& truth = scene.truth_px[static_cast<size_t>(t)];
    const Ellipse& fit = found[static_cast<size_t>(d)].ellipse;
    if (truth.semi_major + truth.semi_minor < 10.0) continue;
    center_errors.push_back((fit.center - truth.center).norm());
    axis_errors.push_back(std::abs(fit.semi_major / truth.semi_major - 1.0));
    axis_errors.push_back(std::abs(fit.semi_minor / truth.semi_minor - 1.0));
  }
  for (const auto& b : score.bins) {
    std::cout << "bin " << b.min_diameter << "-" << b.max_diameter << ": truth " << b.truth
              << " det " << b.detected << " P " << b.precision << " R " << b.recall << "\n";
  }
  for (size_t t = 0; t < scene.truth_px.size(); ++t) {
    const auto& e = scene.truth_px[t];
    bool m = std::any_of(score.matches.begin(), score.matches.end(),
                         [&](auto p) { return p.first == static_cast<int>(t); });
    if (!m) std::cout << "missed " << e.center.transpose() << " D " << 2 * e.MeanRadius() << "\n";
  }
  for (size_t k = 0; k < found.size(); ++k) {
    bool m = std::any_of(score.matches.begin(), score.matches.end(),
                         [&](auto p) { return p.second == static_cast<int>(k); });
    std::cout << (m ? "true " : "false ") << found[k].ellipse.center.transpose() << " D "
              << found[k].Diameter() << " cov " << found[k].coverage << " sig "
              << found[k].signature << " conf " << found[k].confidence << " corr "
              << found[k].shading_correlation << " ec " << found[k].edge_contrast << " rms "
              << found[k].rms_residual << " efs " << found[k].efs << " n "
              << found[k].num_edge_points << "\n";
    if (false)
      std::cout << "false " << found[k].ellipse.center.transpose() << " D " << found[k].Diameter()
                << " cov " << found[k].coverage << " sig " << found[k].signature << " conf "
                << found[k].confidence << "\n";
  }
  std::cout << "time " << seconds << " median center " << Median(center_errors) << " axis "
            << Median(axis_errors) << "\n";
  RecordProperty("seconds", std::to_string(seconds));
  EXPECT_GE(score.all.recall, 0.95);
  EXPECT_GE(score.all.precision, 0.95);
  EXPECT_LT(Median(center_errors), 0.5);
  EXPECT_LT(Median(axis_errors), 0.02);
}

}  // namespace
}  // namespace areomap
