#include "areomap/registration/orbital_match.h"

#include <cmath>
#include <filesystem>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "areomap/map/crs.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/raster.h"
#include "areomap/map/raster_window.h"
#include "orbital_trial.h"
#include "test_support.h"

namespace areomap {
namespace {

using testing::MakeTrial;
using testing::Trial;
using testing::TrialOptions;

// Small trials keep the unit tests fast: a 70 m orbital square and a 30 m rover ortho.
TrialOptions SmallTrial(uint32_t seed) {
  TrialOptions o;
  o.seed = seed;
  o.orbital_half_extent_m = 35.0;
  o.ortho_half_extent_m = 15.0;
  o.telemetry_sigma_m = 2.0;
  return o;
}

double ErrorPx(const OrbitalMatch& m, const Trial& t) {
  return (m.shift_en_m + t.telemetry_error_en_m).norm() / t.gsd_m;
}

TEST(OrbitalMatch, RecoversTheTelemetryErrorAndRejectsADecoy) {
  const Trial trial = MakeTrial(SmallTrial(7));
  const OrbitalMatch m = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
  ASSERT_TRUE(m.matched) << m.BriefReport();
  EXPECT_LE(ErrorPx(m, trial), 0.5) << m.BriefReport();
  EXPECT_TRUE(m.overlaps);
  EXPECT_FALSE(m.window_clipped);
  EXPECT_NEAR(m.gsd_m, 0.25, 1e-3);
  EXPECT_GT(m.correlation, 0.5);
  EXPECT_GE(m.peak_ratio, 1.25);
  EXPECT_EQ(m.surface.empty(), false);
  // The corrected rover position is where the truth is: the telemetry error undone. Without a
  // rotation the rover moves with the template centre.
  const PixelGrid grid(trial.orbital->geotransform(), trial.orbital->crs_wkt(), "orbital");
  const Eigen::Vector2d telemetry = grid.GeographicToPixel(trial.prior.position);
  const Eigen::Vector2d corrected = grid.GeographicToPixel(m.corrected_position);
  EXPECT_FALSE(m.rotation_solved);
  EXPECT_NEAR((corrected - telemetry).x(), m.shift_px.x(), 1e-6);
  EXPECT_NEAR((corrected - telemetry).y(), m.shift_px.y(), 1e-6);
  EXPECT_NEAR(m.corrected_position.h, trial.prior.position.h, 1e-6);

  const OrbitalMatch d = MatchOrthoToOrbital(trial.ortho, *trial.decoy, trial.prior);
  EXPECT_FALSE(d.matched) << d.BriefReport();
  EXPECT_FALSE(d.reason.empty());

  // Several images: each matched, the true one picked.
  const MultiOrbitalMatch multi =
      MatchOrthoToOrbitals(trial.ortho, {*trial.decoy, *trial.orbital}, trial.prior);
  ASSERT_EQ(multi.matches.size(), 2u);
  EXPECT_EQ(multi.best, 1);
}

// A trial whose georeference is turned 3 deg about the rover (a fan of `fan_fov_deg`, 0 =
// random), and its match with a +-5 deg rotation search.
Trial TurnedTrial(double fan_fov_deg) {
  TrialOptions o = SmallTrial(3);
  o.heading_error_deg = 3.0;
  o.fan_fov_deg = fan_fov_deg;
  o.decoy = false;
  return MakeTrial(o);
}

OrbitalMatch MatchWithRotationSearch(const Trial& trial) {
  OrbitalMatchOptions options;
  options.max_rotation_deg = 5.0;
  return MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior, options);
}

TEST(OrbitalMatch, SolvesAHeadingErrorWithTheRotationSearch) {
  const Trial trial = TurnedTrial(0.0);
  const OrbitalMatch m = MatchWithRotationSearch(trial);
  ASSERT_TRUE(m.matched) << m.BriefReport();
  EXPECT_TRUE(m.rotation_solved);
  // The georeference was turned 3 deg counter-clockwise; the correction turns it back. A
  // 0.5 px error at the template's edge (~60 px from its centre) is ~0.5 deg.
  EXPECT_NEAR(m.rotation_rad * 180.0 / std::numbers::pi, -3.0, 0.5) << m.BriefReport();
  EXPECT_LE(ErrorPx(m, trial), 0.5) << m.BriefReport();
  // The turn's sigma is reported (at least the floor), and its error lies within 3 of it.
  ASSERT_GE(m.rotation_sigma_rad, RadFromDeg(OrbitalMatchOptions().rotation_floor_deg));
  EXPECT_LE(std::abs(m.rotation_rad - RadFromDeg(-3.0)), 3.0 * m.rotation_sigma_rad)
      << m.BriefReport();
}

// Below OrbitalMatchOptions::rotation_floor_correlation the rotation's floor grows as
// (g(rho) / g(reference))^2, g(r) = (1 - r^2) / r^2; the same match, judged with the reference
// below and above its correlation, differs in the sigmas alone.
TEST(OrbitalMatch, RotationSigmaGrowsBelowTheReferenceCorrelation) {
  const Trial trial = TurnedTrial(0.0);
  OrbitalMatchOptions options;
  options.max_rotation_deg = 5.0;
  options.rotation_floor_correlation = 0.05;
  const OrbitalMatch high = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior, options);
  ASSERT_TRUE(high.rotation_solved) << high.BriefReport();
  const double rho = high.correlation;
  ASSERT_GT(rho, 0.3);
  ASSERT_LT(rho, 0.95);
  EXPECT_EQ(high.low_correlation_rotation_sigma_rad, 0.0);

  options.rotation_floor_correlation = rho + 0.04;
  const OrbitalMatch low = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior, options);
  ASSERT_TRUE(low.rotation_solved);
  EXPECT_EQ(low.rotation_rad, high.rotation_rad);
  EXPECT_EQ(low.shift_px, high.shift_px);
  EXPECT_EQ(low.rotation_pivot_px, high.rotation_pivot_px);
  const auto g = [](double r) { return (1.0 - r * r) / (r * r); };
  const double floor = RadFromDeg(options.rotation_floor_deg);
  const double grown = floor * std::pow(g(rho) / g(rho + 0.04), 2);
  EXPECT_GT(grown, 1.2 * floor);
  EXPECT_NEAR(low.low_correlation_rotation_sigma_rad, std::sqrt(grown * grown - floor * floor),
              1e-12);
  EXPECT_NEAR(low.rotation_sigma_rad * low.rotation_sigma_rad,
              high.rotation_sigma_rad * high.rotation_sigma_rad + grown * grown - floor * floor,
              1e-15);
  // The rover's covariance holds the larger rotation error; the template's shift does not.
  EXPECT_GT(low.shift_covariance_en_m2.trace(), high.shift_covariance_en_m2.trace());
  EXPECT_EQ(low.template_shift_covariance_en_m2, high.template_shift_covariance_en_m2);
}

TEST(OrbitalMatch, CorrectsTheRoverNotTheTemplateCentreUnderAHeadingError) {
  // A 90 deg fan: the template's centre lies ~7 m from the rover, so a 3 deg turn about the
  // rover moves the centre ~0.4 m (1.5 px) more than the rover. The reported correction is the
  // rover's.
  const Trial trial = TurnedTrial(90.0);
  const OrbitalMatch m = MatchWithRotationSearch(trial);
  ASSERT_TRUE(m.matched) << m.BriefReport();
  ASSERT_TRUE(m.rotation_solved);
  const PixelGrid grid(trial.orbital->geotransform(), trial.orbital->crs_wkt(), "orbital");
  const Eigen::Vector2d rover = grid.GeographicToPixel(trial.prior.position);
  ASSERT_GT((m.centre_px - rover).norm() * trial.gsd_m, 5.0);
  EXPECT_LE(ErrorPx(m, trial), 0.5) << m.BriefReport();
  const Eigen::Vector2d centre_shift_m = grid.EastNorthPerPixel(rover) * m.shift_px;
  EXPECT_GT((centre_shift_m + trial.telemetry_error_en_m).norm() / trial.gsd_m, 1.0)
      << "the template centre's shift is not the rover's here";
}

TEST(OrbitalMatch, ARoverBelowTheEllipsoidIsFoundOnItsOwnRadialLine) {
  // The same rover given 1900 m below the ellipsoid (as a MER site origin is), on the radial
  // line of its map pixel: its foot point on the ellipsoid lies 5.5 m north of that line, and
  // the match must not move there.
  const Trial trial = MakeTrial(SmallTrial(7));
  const PixelGrid grid(trial.orbital->geotransform(), trial.orbital->crs_wkt(), "orbital");
  const Body body = Body::Mars2000();
  const Eigen::Vector2d pixel = grid.GeographicToPixel(trial.prior.position);
  const Eigen::Vector3d below =
      MbfOnRadialLine(body, trial.prior.position.lat, trial.prior.position.lon, -1900.0);
  EXPECT_LT((grid.PointToPixel(below) - pixel).norm(), 1e-6);
  EXPECT_GT((grid.GeographicToPixel(GeographicFromMbf(body, below)) - pixel).norm() * trial.gsd_m,
            5.0);

  OrbitalPrior deep = trial.prior;
  deep.position = GeographicFromMbf(body, below);
  const OrbitalMatch at_surface = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
  const OrbitalMatch at_depth = MatchOrthoToOrbital(trial.ortho, *trial.orbital, deep);
  ASSERT_TRUE(at_depth.matched) << at_depth.BriefReport();
  EXPECT_LT((at_depth.shift_en_m - at_surface.shift_en_m).norm(), 1e-6);
  EXPECT_LE(ErrorPx(at_depth, trial), 0.5);
  EXPECT_NEAR(at_depth.corrected_position.h, -1900.0, 1e-6);
  const auto corrected_pixel = [&](const OrbitalMatch& m) -> Eigen::Vector2d {
    return grid.PointToPixel(MbfFromGeographic(body, m.corrected_position));
  };
  EXPECT_LT((corrected_pixel(at_depth) - corrected_pixel(at_surface)).norm(), 1e-4);
}

TEST(OrbitalMatch, ASearchWindowOffTheImageIsNoMatch) {
  TrialOptions o = SmallTrial(5);
  o.decoy = false;
  Trial trial = MakeTrial(o);
  // Move the ortho and the prior 1 km east: nothing of the search window is on the image.
  trial.ortho.geotransform.c[0] += 1000.0;
  const PixelGrid grid(trial.ortho.geotransform, trial.ortho.crs_wkt, "ortho");
  trial.prior.position =
      *grid.PixelToGeographic({trial.ortho.image.cols / 2.0, trial.ortho.image.rows / 2.0});
  const OrbitalMatch m = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
  EXPECT_FALSE(m.overlaps);
  EXPECT_FALSE(m.matched);
  EXPECT_NE(m.reason.find("does not overlap"), std::string::npos) << m.reason;
}

// An orthophoto of another region altogether (the MOC image against a rover site 49 degrees of
// latitude away, found by the CLI audit): no overlap, not an orthophoto without valid pixels,
// whatever the template resampled to.
TEST(OrbitalMatch, AnOrthoFarOffTheImageIsNoOverlapEvenWithAnEmptyTemplate) {
  TrialOptions o = SmallTrial(5);
  o.decoy = false;
  Trial trial = MakeTrial(o);
  trial.ortho.geotransform.c[3] += 3.0e6;  // 3000 km north
  const PixelGrid grid(trial.ortho.geotransform, trial.ortho.crs_wkt, "ortho");
  trial.prior.position =
      *grid.PixelToGeographic({trial.ortho.image.cols / 2.0, trial.ortho.image.rows / 2.0});
  OrbitalMatchOptions options;
  options.min_template_pixels = 1 << 30;  // as if the template had come out empty
  const OrbitalMatch m = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior, options);
  EXPECT_FALSE(m.overlaps);
  EXPECT_NE(m.reason.find("does not overlap"), std::string::npos) << m.reason;
  // Over the image, too few pixels are still the orthophoto's fault.
  const Trial near = MakeTrial(o);
  const OrbitalMatch n = MatchOrthoToOrbital(near.ortho, *near.orbital, near.prior, options);
  EXPECT_TRUE(n.overlaps);
  EXPECT_NE(n.reason.find("valid pixels within the reliable range"), std::string::npos) << n.reason;
}

TEST(OrbitalMatch, AnAllNodataOrthoIsNoMatch) {
  TrialOptions o = SmallTrial(5);
  o.decoy = false;
  Trial trial = MakeTrial(o);
  trial.ortho.image.setTo(std::numeric_limits<float>::quiet_NaN());
  const OrbitalMatch m = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
  EXPECT_FALSE(m.matched);
  EXPECT_NE(m.reason.find("valid pixels"), std::string::npos) << m.reason;
}

TEST(OrbitalMatch, ASearchWindowLargerThanTheImageIsClippedAndStillMatches) {
  TrialOptions o = SmallTrial(9);
  o.decoy = false;
  Trial trial = MakeTrial(o);
  trial.prior.sigma_m = 30.0;  // 3 sigma = 90 m, on a 70 m image.
  const OrbitalMatch m = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
  EXPECT_TRUE(m.window_clipped);
  EXPECT_EQ(m.search_radius_px, 360);  // 90 m at 0.25 m.
  EXPECT_FALSE(m.surface.empty());
  ASSERT_TRUE(m.matched) << m.BriefReport();
  EXPECT_LE(ErrorPx(m, trial), 0.5) << m.BriefReport();
}

TEST(OrbitalMatch, AnOrthoOnEarthIsRejectedWithItsName) {
  TrialOptions o = SmallTrial(5);
  o.decoy = false;
  Trial trial = MakeTrial(o);
  trial.ortho.crs_wkt = Crs::FromUserInput("EPSG:32633").Wkt();
  trial.ortho.source = "earth_ortho.tif";
  const std::string message = areomap::testing::ErrorMessageOf(
      [&] { MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior); });
  EXPECT_NE(message.find("earth_ortho.tif"), std::string::npos) << message;
  EXPECT_NE(message.find("not on Mars"), std::string::npos) << message;
}

TEST(OrbitalMatchOptions, CheckNamesTheField) {
  OrbitalMatchOptions options;
  EXPECT_NO_THROW(options.Check());
  options.max_false_match = 0.0;
  std::string message = areomap::testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("OrbitalMatchOptions.max_false_match"), std::string::npos) << message;
  options = {};
  options.template_options.min_coverage = 0.0;
  message = areomap::testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("TemplateOptions.min_coverage"), std::string::npos) << message;
  options = {};
  options.rotation_floor_deg = -0.1;
  message = areomap::testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("OrbitalMatchOptions.rotation_floor_deg"), std::string::npos) << message;
  options = {};
  options.rotation_floor_correlation = 1.0;
  message = areomap::testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("OrbitalMatchOptions.rotation_floor_correlation"), std::string::npos)
      << message;
}

// The orthophoto as a single-band Float32 GeoTIFF inside a nodata margin of `margin` pixels on
// every side (NaN nodata, as a georeferencing tool writes it).
void WriteWithNodataMargin(const OrthoImage& ortho, int margin, const std::filesystem::path& path) {
  cv::Mat values(ortho.image.rows + 2 * margin, ortho.image.cols + 2 * margin, CV_32F,
                 cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  cv::Mat inner = values(cv::Rect(margin, margin, ortho.image.cols, ortho.image.rows));
  ortho.image.copyTo(inner, ortho.ValidMask());
  GeoRaster raster;
  raster.bands = {values};
  raster.geotransform =
      WindowTransform(ortho.geotransform, PixelWindow{-margin, -margin, values.cols, values.rows});
  raster.crs_wkt = ortho.crs_wkt;
  raster.nodata = std::numeric_limits<double>::quiet_NaN();
  WriteGeoTiff(path, raster);
}

// Only the window of the valid pixels is read (memory by the data, not the raster), and the match
// is the one of the whole orthophoto.
TEST(OrbitalMatch, ReadsOnlyTheValidWindowAndMatchesAsTheWholeOrtho) {
  const Trial trial = MakeTrial(SmallTrial(7));
  const areomap::testing::TempDir dir;
  WriteWithNodataMargin(trial.ortho, 300, dir.path() / "padded.tif");
  const OrthoImage read = ReadOrthoImage(dir.path() / "padded.tif");
  std::vector<cv::Point> valid;
  cv::findNonZero(trial.ortho.ValidMask(), valid);
  const cv::Rect box = cv::boundingRect(valid);
  EXPECT_EQ(read.image.size(), box.size());
  const Eigen::Vector2d origin = trial.ortho.geotransform.PixelToMap(box.x, box.y);
  EXPECT_NEAR(read.geotransform.c[0], origin.x(), 1e-6);
  EXPECT_NEAR(read.geotransform.c[3], origin.y(), 1e-6);

  const OrbitalMatch whole = MatchOrthoToOrbital(trial.ortho, *trial.orbital, trial.prior);
  const OrbitalMatch window = MatchOrthoToOrbital(read, *trial.orbital, trial.prior);
  ASSERT_TRUE(whole.matched) << whole.BriefReport();
  ASSERT_TRUE(window.matched) << window.BriefReport();
  EXPECT_LT((window.shift_px - whole.shift_px).norm(), 1e-3) << window.BriefReport();
  EXPECT_NEAR(window.rotation_rad, whole.rotation_rad, 1e-6);
}

// An orthophoto with no valid pixel is refused, naming the file, once band 1 has been scanned.
TEST(OrbitalMatch, AllNodataOrthoIsRefusedNamingTheFile) {
  const areomap::testing::TempDir dir;
  GeoRaster raster;
  raster.bands = {cv::Mat(64, 96, CV_32F, cv::Scalar(-9999.0f))};
  raster.geotransform = GeoTransform::NorthUp(1000.0, 2000.0, 0.25, -0.25);
  raster.crs_wkt = Crs::FromUserInput("+proj=eqc +R=3396190 +units=m +no_defs").Wkt();
  raster.nodata = -9999.0;
  WriteGeoTiff(dir.path() / "nodata.tif", raster);
  EXPECT_EQ(testing::ErrorMessageOf([&] { ReadOrthoImage(dir.path() / "nodata.tif"); }),
            (dir.path() / "nodata.tif").string() +
                ": band 1 has no valid pixel (every value is nodata or not finite): expected an "
                "orthophoto with image values");
}

}  // namespace
}  // namespace areomap

namespace areomap {
namespace {

// The orthophoto on another Mars projection than the orbital image (a sinusoidal one on the
// IAU sphere, warped by gdalwarp, independently of areomap), read back from a 2-band GeoTIFF
// (values + validity mask): the match goes through planetocentric coordinates.
TEST(OrbitalMatch, MatchesAnOrthoOnAnotherProjectionReadFromGeoTiff) {
  TrialOptions o = SmallTrial(13);
  o.decoy = false;
  const Trial trial = MakeTrial(o);
  const areomap::testing::TempDir dir;
  GeoRaster raster;
  cv::Mat mask;
  trial.ortho.ValidMask().convertTo(mask, CV_32F, 1.0 / 255.0);
  cv::Mat values = trial.ortho.image.clone();
  values.setTo(0.0f, mask == 0.0f);
  raster.bands = {values, mask};
  raster.geotransform = trial.ortho.geotransform;
  raster.crs_wkt = trial.ortho.crs_wkt;
  WriteGeoTiff(dir.path() / "ortho.tif", raster);
  const auto warped = dir.path() / "ortho_sinu.tif";
  areomap::testing::RunCommand(
      "gdalwarp -q -r bilinear -t_srs '+proj=sinu +lon_0=175 +R=3396190 +units=m +no_defs' " +
      (dir.path() / "ortho.tif").string() + " " + warped.string());
  const OrthoImage ortho = ReadOrthoImage(warped);
  ASSERT_FALSE(ortho.mask.empty());
  EXPECT_NE(ortho.crs_wkt, trial.orbital->crs_wkt());
  const OrbitalMatch m = MatchOrthoToOrbital(ortho, *trial.orbital, trial.prior);
  ASSERT_TRUE(m.matched) << m.BriefReport();
  EXPECT_LE(ErrorPx(m, trial), 0.5) << m.BriefReport();
}

}  // namespace
}  // namespace areomap
