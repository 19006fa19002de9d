// Guided orbital registration (OrbitalPrior::expected_shift_en_m / expected_rotation_rad with
// OrbitalMatchOptions::null_windows): what `areomap run` does for a site that did not register
// around its telemetry position, once the bundle adjustment knows where the site is.
#include <cmath>
#include <numbers>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/raster.h"
#include "areomap/registration/orbital_match.h"
#include "orbital_trial.h"
#include "test_support.h"

namespace areomap {
namespace {

using testing::MakeTrial;
using testing::Trial;
using testing::TrialOptions;

// A long way down a traverse: 12 m telemetry error and a 9 degree heading error, beyond the
// +-5 degree rotation grid `areomap run` searches around telemetry.
Trial DriftedTrial(uint32_t seed) {
  TrialOptions o;
  o.seed = seed;
  o.orbital_half_extent_m = 45.0;
  o.ortho_half_extent_m = 15.0;
  o.telemetry_sigma_m = 12.0;
  o.heading_error_deg = 9.0;
  return MakeTrial(o);
}

OrbitalMatchOptions RunOptions() {
  OrbitalMatchOptions options;
  options.max_rotation_deg = 5.0;
  return options;
}

// The prior an adjustment gives: the correction (minus the telemetry error) known to about
// 0.5 m and 1 degree, here off by 0.4 m east, -0.3 m north and 0.8 degrees.
OrbitalPrior AdjustedPrior(const Trial& trial) {
  OrbitalPrior prior = trial.prior;
  prior.sigma_m = 0.5;
  prior.expected_shift_en_m = -trial.telemetry_error_en_m + Eigen::Vector2d(0.4, -0.3);
  prior.expected_rotation_rad = (-9.0 + 0.8) * std::numbers::pi / 180.0;
  return prior;
}

// Distance [orbital px] between where the match puts the rover (the similarity applied to its
// telemetry pixel: with a turn the template centre's shift is not the rover's) and the truth.
double RoverErrorPx(const OrbitalMatch& m, const Trial& t) {
  const PixelGrid orbital(t.orbital->geotransform(), t.orbital->crs_wkt(), "orbital");
  const PixelGrid truth(t.ortho_truth, t.ortho.crs_wkt, "truth");
  const Eigen::Vector2d telemetry = orbital.GeographicToPixel(t.prior.position);
  const Eigen::Vector2d corrected =
      m.TemplateToOrbital(telemetry - Eigen::Vector2d(m.templ.col0, m.templ.row0));
  const Eigen::Vector2d centre(t.ortho.image.cols / 2.0, t.ortho.image.rows / 2.0);
  return (corrected - orbital.GeographicToPixel(*truth.PixelToGeographic(centre))).norm();
}

TEST(GuidedOrbitalMatch, RegistersWhereTheTelemetryWindowFailsAndBeatsChance) {
  const Trial trial = DriftedTrial(11);
  Trial wide = trial;
  wide.prior.sigma_m = 12.0;
  const OrbitalMatch telemetry =
      MatchOrthoToOrbital(trial.ortho, *trial.orbital, wide.prior, RunOptions());
  // Around telemetry the turned orthophoto gives no confident match, or a wrong one.
  EXPECT_TRUE(!telemetry.matched || RoverErrorPx(telemetry, trial) > 2.0)
      << telemetry.BriefReport();

  OrbitalMatchOptions options = RunOptions();
  options.null_windows = 48;
  const OrbitalMatch guided =
      MatchOrthoToOrbital(trial.ortho, *trial.orbital, AdjustedPrior(trial), options);
  ASSERT_TRUE(guided.matched) << guided.BriefReport();
  // Area correlation at the orbital resolution: half a pixel, as around telemetry.
  EXPECT_LE(RoverErrorPx(guided, trial), 0.5) << guided.BriefReport();
  EXPECT_NEAR(guided.rotation_rad * 180.0 / std::numbers::pi, -9.0, 0.5) << guided.BriefReport();
  // A 3 sigma = 1.5 m window (6 px) around the adjusted position.
  EXPECT_EQ(guided.search_radius_px, 6);
  EXPECT_GE(guided.null_windows, 48);
  EXPECT_EQ(guided.null_reaching, 0);
  EXPECT_LT(guided.null_highest, guided.correlation);
  EXPECT_LE(guided.false_match_probability, options.max_false_match);
}

TEST(GuidedOrbitalMatch, AWindowOnTheWrongGroundOrWithoutTextureRefuses) {
  const Trial trial = DriftedTrial(11);
  OrbitalMatchOptions options = RunOptions();
  options.null_windows = 48;
  // Other ground with texture of the same kind (the decoy scene on the same grid): in a small
  // window some peak always exists; the chance level must refuse it.
  const OrbitalMatch decoy =
      MatchOrthoToOrbital(trial.ortho, *trial.decoy, AdjustedPrior(trial), options);
  EXPECT_FALSE(decoy.matched) << decoy.BriefReport();
  // The chance level says why: the decoy's best peak is one a window of that size holds by chance.
  EXPECT_NE(decoy.reason.find("false-match probability"), std::string::npos) << decoy.reason;
  EXPECT_GT(decoy.false_match_probability, options.max_false_match);

  // An orbital image without texture at the rover's scale: the true one blurred to 10 m.
  PixelWindow all{0, 0, 1 << 20, 1 << 20};
  GeoRaster smooth;
  smooth.bands.push_back(trial.orbital->ReadWindow(all));
  cv::GaussianBlur(smooth.bands[0], smooth.bands[0], cv::Size(), 40.0);
  smooth.geotransform = trial.orbital->geotransform();
  smooth.crs_wkt = trial.orbital->crs_wkt();
  const OrbitalImage flat = OrbitalImage::FromGeoRaster(smooth, "smooth");
  const OrbitalMatch untextured =
      MatchOrthoToOrbital(trial.ortho, flat, AdjustedPrior(trial), options);
  EXPECT_FALSE(untextured.matched) << untextured.BriefReport();
}

TEST(GuidedOrbitalMatch, OptionsAndPriorAreChecked) {
  OrbitalMatchOptions options;
  options.null_windows = -1;
  std::string message = areomap::testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("OrbitalMatchOptions.null_windows"), std::string::npos) << message;
  options = {};
  options.min_null_samples = 4;
  message = areomap::testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("OrbitalMatchOptions.min_null_samples"), std::string::npos) << message;

  TrialOptions o;
  o.orbital_half_extent_m = 20.0;
  o.ortho_half_extent_m = 10.0;
  o.decoy = false;
  const Trial trial = MakeTrial(o);
  OrbitalPrior prior = trial.prior;
  prior.expected_rotation_rad = std::nan("");
  message = areomap::testing::ErrorMessageOf(
      [&] { MatchOrthoToOrbital(trial.ortho, *trial.orbital, prior); });
  EXPECT_NE(message.find("OrbitalPrior.expected_rotation_rad"), std::string::npos) << message;
}

}  // namespace
}  // namespace areomap
