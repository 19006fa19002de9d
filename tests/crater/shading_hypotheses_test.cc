#include "areomap/crater/shading_hypotheses.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/crater/crater_score.h"
#include "areomap/map/error.h"
#include "crater_scene.h"

namespace areomap {
namespace {

using testing::CraterScene;
using testing::MakeCraterScene;

constexpr double kSunAzimuth = 120.0;

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? std::numeric_limits<double>::quiet_NaN() : v[v.size() / 2];
}

// 400 x 400 px at 0.5 m/px, sun 30 degrees high from azimuth 120: 20 degraded bowls 8-24 px
// across (depth/diameter 0.05-0.09, rim 0.5 % of the diameter high, as infilled and eroded simple
// craters) on a 5 x 4 grid with jitter, among 4 fresh craters 16-32 px, on the generator's
// rolling, textured plain.
const CraterScene& DegradedScene() {
  static const CraterScene scene = [] {
    SceneOptions s;
    s.half_extent_m = 100.0;
    s.crater_count = 4;
    s.crater_min_diameter_m = 8.0;
    s.crater_max_diameter_m = 16.0;
    s.seed = 11;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int k = 0; k < 20; ++k) {
      Crater c;
      const double diameter = 4.0 * std::pow(3.0, unit(rng));
      c.center = {-80.0 + 40.0 * (k % 5) + 8.0 * (unit(rng) - 0.5),
                  -60.0 + 40.0 * (k / 5) + 8.0 * (unit(rng) - 0.5)};
      c.semi_major = c.semi_minor = 0.5 * diameter;
      c.depth = diameter * (0.05 + 0.04 * unit(rng));
      c.rim_height = 0.005 * diameter;
      s.explicit_craters.push_back(c);
    }
    OrbitalImageOptions o;
    o.gsd_m = 0.5;
    o.sun_azimuth_deg = kSunAzimuth;
    o.sun_elevation_deg = 30.0;
    o.supersample = 1;
    return MakeCraterScene(s, o, 1.0);
  }();
  return scene;
}

TEST(ShadingHypotheses, FindsDegradedBowlsThatTheEdgePathMisses) {
  const CraterScene& scene = DegradedScene();
  const cv::Mat& image = scene.products.image.bands[0];
  CraterDetectorOptions options;
  options.sun_azimuth_deg = kSunAzimuth;
  options.shading_template.enabled = false;
  const std::vector<CraterDetection> edge_only = DetectCraters(image, RimSource::kImage, options);
  options.shading_template.enabled = true;
  const std::vector<CraterDetection> found = DetectCraters(image, RimSource::kImage, options);
  const std::vector<double> bins = {8.0, 1e9};
  const CraterScore before = ScoreCraters(CirclesOf(scene.truth_px), CirclesOf(edge_only), bins);
  const CraterScore after = ScoreCraters(CirclesOf(scene.truth_px), CirclesOf(found), bins);
  std::vector<double> center_errors, radius_errors;
  int template_only = 0;
  for (const auto& [t, d] : after.matches) {
    const CraterDetection& detection = found[static_cast<size_t>(d)];
    if (!std::isnan(detection.efs)) continue;  // an edge fit, not the template's circle
    ++template_only;
    const Ellipse& truth = scene.truth_px[static_cast<size_t>(t)];
    center_errors.push_back((detection.ellipse.center - truth.center).norm());
    radius_errors.push_back(std::abs(detection.ellipse.MeanRadius() / truth.MeanRadius() - 1.0));
  }
  RecordProperty("edge_only_recall", std::to_string(before.all.recall));
  RecordProperty("recall", std::to_string(after.all.recall));
  RecordProperty("precision", std::to_string(after.all.precision));
  RecordProperty("template_only_matches", template_only);
  RecordProperty("template_median_center_error_px", std::to_string(Median(center_errors)));
  RecordProperty("template_median_radius_error", std::to_string(Median(radius_errors)));
  // The scene is hard for rim edges: the shallow bowls show edges only along the sun line.
  EXPECT_LT(before.all.recall, 0.8);
  EXPECT_GE(after.all.recall, 0.95);
  EXPECT_GE(after.all.precision, 0.9);
  EXPECT_GE(template_only, 5);
  // Template circles: sub-pixel correlation peak across the sun line, the two sub-pixel rim
  // edges along it and the radius between templates 2^(1/4) = 1.19 apart: the issue's
  // half-pixel centre bound, and the radius well inside one template step.
  EXPECT_LT(Median(center_errors), 0.5);
  EXPECT_LT(Median(radius_errors), 0.05);
}

// A bowl rendered analytically: Lambert shading of z = depth (r / R)^2 inside R, flat outside.
cv::Mat BowlImage(int size, const Eigen::Vector2d& center, double radius, double depth_ratio,
                  double sun_azimuth_deg, double sign = 1.0) {
  const double az = sun_azimuth_deg * std::numbers::pi / 180.0;
  const Eigen::Vector3d sun =
      Eigen::Vector3d(std::sin(az), -std::cos(az), std::tan(std::numbers::pi / 6.0)).normalized();
  cv::Mat image(size, size, CV_32F);
  const double depth = depth_ratio * 2.0 * radius;
  for (int r = 0; r < size; ++r) {
    for (int c = 0; c < size; ++c) {
      const Eigen::Vector2d d = Eigen::Vector2d(c + 0.5, r + 0.5) - center;
      const Eigen::Vector2d slope =
          d.norm() < radius ? Eigen::Vector2d(sign * 2.0 * depth * d / (radius * radius))
                            : Eigen::Vector2d::Zero();
      const Eigen::Vector3d normal = Eigen::Vector3d(-slope.x(), -slope.y(), 1.0).normalized();
      image.at<float>(r, c) = static_cast<float>(500.0 * std::max(0.0, normal.dot(sun)));
    }
  }
  return image;
}

TEST(ShadingHypotheses, PeakAtTheBowlAndNotAtAMoundOrAnEdge) {
  const Eigen::Vector2d center(40.3, 37.8);
  const cv::Mat bowl = BowlImage(80, center, 6.0, 0.1, kSunAzimuth);
  const std::vector<ShadingHypothesis> found = FindShadingHypotheses(bowl, kSunAzimuth, 3.0, 20.0);
  ASSERT_FALSE(found.empty());
  // Radius 6 runs on the 2x2-averaged copy (radius 3 there): the sub-pixel peak within half a
  // pixel of that copy.
  EXPECT_LT((found[0].center - center).norm(), 1.0);
  EXPECT_NEAR(found[0].radius, 6.0, 0.6);
  EXPECT_GT(found[0].correlation, 0.9);
  // The same relief raised (a mound) shades the other way round; the sun from the opposite side
  // likewise.
  const cv::Mat mound = BowlImage(80, center, 6.0, 0.1, kSunAzimuth, -1.0);
  for (const ShadingHypothesis& h : FindShadingHypotheses(mound, kSunAzimuth, 3.0, 20.0)) {
    EXPECT_GT((h.center - center).norm(), 6.0) << h.correlation;
  }
  for (const ShadingHypothesis& h : FindShadingHypotheses(bowl, kSunAzimuth + 180.0, 3.0, 20.0)) {
    EXPECT_GT((h.center - center).norm(), 6.0) << h.correlation;
  }
  // A straight brightness step across the sun line (a scarp) correlates below 0.6.
  cv::Mat step(80, 80, CV_32F, cv::Scalar(100.0));
  step.colRange(40, 80).setTo(300.0);
  EXPECT_TRUE(FindShadingHypotheses(step, 90.0, 3.0, 20.0).empty());
}

TEST(ShadingHypotheses, FeaturelessAndNodataImages) {
  EXPECT_TRUE(
      FindShadingHypotheses(cv::Mat(100, 100, CV_16U, cv::Scalar(700)), 90.0, 3.0, 30.0).empty());
  EXPECT_TRUE(FindShadingHypotheses(cv::Mat(5, 5, CV_8U, cv::Scalar(7)), 90.0, 3.0, 30.0).empty());
  const cv::Mat nodata(100, 100, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  EXPECT_TRUE(FindShadingHypotheses(nodata, 90.0, 3.0, 30.0).empty());
  // A bowl next to a nodata hole: no hypothesis whose window touches the hole.
  cv::Mat bowl = BowlImage(80, {40.0, 40.0}, 6.0, 0.1, kSunAzimuth);
  bowl.colRange(0, 20).setTo(std::numeric_limits<float>::quiet_NaN());
  for (const ShadingHypothesis& h : FindShadingHypotheses(bowl, kSunAzimuth, 3.0, 20.0)) {
    EXPECT_GT(h.center.x() - std::ceil(1.6 * h.radius), 19.0);
    EXPECT_TRUE(std::isfinite(h.correlation));
  }
}

TEST(ShadingHypotheses, OptionsNameTheBadField) {
  ShadingTemplateOptions o;
  o.min_correlation = 1.5;
  try {
    o.Check();
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("min_correlation"), std::string::npos) << e.what();
  }
  CraterDetectorOptions detector;
  detector.shading_template.radii_per_octave = 0;
  EXPECT_THROW(detector.Check(), Error);
  EXPECT_THROW(BowlShadingTemplate(0.5, 90.0), Error);
  EXPECT_THROW(FindShadingHypotheses(cv::Mat(10, 10, CV_8UC3), 90.0, 3.0, 5.0), Error);
}

}  // namespace
}  // namespace areomap
