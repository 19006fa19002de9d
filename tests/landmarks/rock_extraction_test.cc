#include "areomap/landmarks/rock_extraction.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "areomap/landmarks/rock_output.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/samples/simulated_points.h"
#include "test_support.h"

namespace areomap {
namespace {

Scene RockyScene() {
  SceneOptions options;
  options.half_extent_m = 60.0;
  options.crater_count = 0;
  options.roughness_m = 0.3;
  options.rock_path = {Eigen::Vector2d(-30, 0), Eigen::Vector2d(30, 0)};
  options.rock_abundance_k = 0.08;
  options.rock_corridor_m = 15.0;
  options.seed = 5;
  return Scene(options);
}

// Site-frame (x north, y east) horizontal position of an ENU point seen from `site`.
Eigen::Vector2d SiteXY(const Eigen::Vector2d& enu, const Eigen::Vector2d& site) {
  return {enu.y() - site.y(), enu.x() - site.x()};
}

// How far a peak may lie from the rock's footprint: 3 horizontal sigmas of the peak point (the
// range error of eq. 4.3 is ~17 cm at 9 m) plus 10 cm for a tilted rock's top.
double Reach(const ExtractedRock& e) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(
      e.peak_covariance.topLeftCorner<2, 2>());
  return 3.0 * std::sqrt(eigen.eigenvalues().maxCoeff()) + 0.10;
}

struct Detection {
  int truth = 0, found = 0, extracted_near = 0, false_positives = 0;
  double worst_height_excess = 0.0;  // max(|H - h| - allowed), <= 0 when all are within.
  double mean_abs_height_error = 0.0;
};

// Compares the extraction with the scene's rocks of height >= min_height within 3-10 m of the
// site and inside the simulated azimuths (5 degrees of margin).
Detection Evaluate(const Scene& scene, const Eigen::Vector2d& site,
                   const std::vector<ExtractedRock>& rocks, double min_height, double az_max_deg) {
  Detection d;
  const auto inside = [&](const Eigen::Vector2d& xy, double margin_deg) {
    const double range = xy.norm();
    const double az = std::atan2(xy.y(), xy.x()) * 180.0 / std::numbers::pi;
    return range >= 3.0 && range <= 10.0 && az >= margin_deg && az <= az_max_deg - margin_deg;
  };
  for (const Rock& r : scene.rocks()) {
    const Eigen::Vector2d xy = SiteXY(r.center, site);
    if (r.height < min_height || !inside(xy, 5.0)) continue;
    ++d.truth;
    const ExtractedRock* match = nullptr;  // The nearest peak within reach.
    double nearest = 1e9;
    for (const ExtractedRock& e : rocks) {
      const double distance = (e.peak.head<2>() - xy).norm();
      if (distance < r.a + Reach(e) && distance < nearest) {
        match = &e;
        nearest = distance;
      }
    }
    if (!match) continue;
    ++d.found;
    // H is measured from the peak, the highest of noisy points: allow 3 vertical sigmas of the
    // peak (eq. 4.3 noise) plus 3 cm for the ground plane and a tilted rock's top.
    const double error = std::abs(match->height_m - r.height);
    const double allowed = 3.0 * std::sqrt(match->peak_covariance(2, 2)) + 0.03;
    d.worst_height_excess = std::max(d.worst_height_excess, error - allowed);
    d.mean_abs_height_error += error;
  }
  if (d.found > 0) d.mean_abs_height_error /= d.found;
  // False positives: extracted rocks (H >= 0.15 m) with no true rock of any size under them.
  for (const ExtractedRock& e : rocks) {
    if (e.height_m < 0.15 || !inside(e.peak.head<2>(), 0.0)) continue;
    ++d.extracted_near;
    bool real = false;
    for (const Rock& r : scene.rocks()) {
      real = real || (SiteXY(r.center, site) - e.peak.head<2>()).norm() < r.a + Reach(e);
    }
    d.false_positives += real ? 0 : 1;
  }
  return d;
}

TEST(RockExtraction, FindsTheSceneRocksWithHeightsWithinTheStereoError) {
  const Scene scene = RockyScene();
  SimulatedPointsOptions sim;
  sim.azimuth_max_deg = 120.0;
  sim.max_range_m = 12.0;
  const Eigen::Vector2d site(0.0, 0.0);
  const PointCloud cloud = SimulateSitePointCloud(scene, site, 0, sim);
  RockExtractionSummary summary;
  const std::vector<ExtractedRock> rocks = ExtractRocks(cloud, {}, &summary);
  EXPECT_EQ(summary.rocks, static_cast<int>(rocks.size()));
  const Detection d = Evaluate(scene, site, rocks, 0.15, sim.azimuth_max_deg);
  ASSERT_GE(d.truth, 10);
  // Rocks >= 15 cm within 10 m: at least 80 % found (the simulated cloud samples the ground
  // every ~20 cm in range at 9 m, so the smallest far rocks get only a few points).
  EXPECT_GE(d.found, 0.8 * d.truth) << d.found << " of " << d.truth;
  EXPECT_LE(d.worst_height_excess, 0.0);
  EXPECT_LT(d.mean_abs_height_error, 0.03);
  EXPECT_LE(d.false_positives, std::max(1, d.extracted_near / 10))
      << d.false_positives << " of " << d.extracted_near;
  // Rocks near the camera carry enough surface points for a model.
  int near_modeled = 0, near_total = 0;
  for (const ExtractedRock& e : rocks) {
    if (e.range_m > 6.0 || e.height_m < 0.15) continue;
    ++near_total;
    near_modeled += e.modeled() ? 1 : 0;
    if (e.modeled()) {
      // The rock frame puts the peak's foot at the origin with z up along the plane normal.
      const Eigen::Vector3d peak_in_rock = e.rock_from_site * e.peak;
      EXPECT_NEAR(peak_in_rock.z(), e.height_m, 1e-9);
      EXPECT_NEAR(peak_in_rock.head<2>().norm(), 0.0, 1e-9);
    }
  }
  EXPECT_GE(near_modeled, 0.8 * near_total);
}

// The catalogue files: one CSV row per rock (best model or empty model fields), the JSON with
// every model, and the plot; a cloud with nothing in range cannot be plotted.
TEST(RockExtraction, CatalogueFilesHoldEveryRock) {
  const Scene scene = RockyScene();
  SimulatedPointsOptions sim;
  sim.azimuth_max_deg = 60.0;
  sim.max_range_m = 8.0;
  const PointCloud cloud = SimulateSitePointCloud(scene, {0.0, 0.0}, 0, sim);
  const std::vector<ExtractedRock> rocks = ExtractRocks(cloud, {});
  ASSERT_GE(rocks.size(), 3u);
  testing::TempDir dir;
  WriteRocksCsv(dir.path() / "rocks.csv", rocks);
  WriteRocksJson(dir.path() / "rocks.json", rocks);
  WriteRocksPlotPng(dir.path() / "rocks.png", cloud, rocks, 30.0, 400);
  std::ifstream csv(dir.path() / "rocks.csv");
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(csv, line)) lines.push_back(line);
  ASSERT_EQ(lines.size(), rocks.size() + 1);
  EXPECT_EQ(lines[0].rfind("id,x_m,y_m,z_m,", 0), 0u);
  const auto fields = [](const std::string& row) {
    return static_cast<int>(std::count(row.begin(), row.end(), ',')) + 1;
  };
  for (const std::string& row : lines) EXPECT_EQ(fields(row), fields(lines[0])) << row;
  std::ifstream json_file(dir.path() / "rocks.json");
  const nlohmann::json json = nlohmann::json::parse(json_file);
  ASSERT_EQ(json["rocks"].size(), rocks.size());
  EXPECT_EQ(json["rocks"][0]["id"].get<int>(), rocks[0].id);
  EXPECT_EQ(json["rocks"][0]["models"].size(), rocks[0].models.size());
  EXPECT_NEAR(json["rocks"][0]["height_m"].get<double>(), rocks[0].height_m, 1e-12);
  EXPECT_GT(std::filesystem::file_size(dir.path() / "rocks.png"), 1000u);
  // The overlay: each rock's surface points painted at their left-image pixels.
  const cv::Mat left(600, 800, CV_8UC1, cv::Scalar(90));
  const cv::Mat overlay = RenderRocksImage(left, cloud, rocks, 0, "left.png");
  ASSERT_EQ(overlay.type(), CV_8UC3);
  int painted = 0, inside = 0;
  for (const ExtractedRock& r : rocks) {
    for (int index : r.surface_indices) {
      const StereoPoint& p = cloud.points[static_cast<size_t>(index)];
      const cv::Point q(static_cast<int>(std::lround(p.left_x)),
                        static_cast<int>(std::lround(p.left_y)));
      if (!cv::Rect(0, 0, overlay.cols, overlay.rows).contains(q)) continue;
      ++inside;
      const cv::Vec3b v = overlay.at<cv::Vec3b>(q);
      // Red or orange (RGB; labels are in the rocks' colours too), or the yellow peak cross
      // drawn over it; never the grey background.
      painted +=
          v == cv::Vec3b(255, 0, 0) || v == cv::Vec3b(255, 165, 0) || v == cv::Vec3b(255, 255, 0)
              ? 1
              : 0;
    }
  }
  ASSERT_GT(inside, 20);
  EXPECT_EQ(painted, inside);
  // A 16-bit RGBA image is stretched and loses its alpha; a 2 x 2 image that the cloud's pixels
  // miss is the wrong image: an error naming it.
  EXPECT_EQ(RenderRocksImage(cv::Mat(600, 800, CV_16UC4, cv::Scalar(100, 200, 300, 65535)), cloud,
                             rocks, 0, "rgba.png")
                .type(),
            CV_8UC3);
  try {
    RenderRocksImage(cv::Mat(2, 2, CV_8UC1, cv::Scalar(0)), cloud, rocks, 0, "tiny.png");
    ADD_FAILURE() << "no error for an image the rocks miss";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("tiny.png"), std::string::npos) << e.what();
  }
  // No point in range: a blank map with a note (an empty result, not an error).
  PointCloud far = cloud;
  far.camera_center = Eigen::Vector3d(1000.0, 0.0, 0.0);
  WriteRocksPlotPng(dir.path() / "far.png", far, rocks, 30.0, 400);
  cv::Mat blank;
  cv::cvtColor(ReadImage(dir.path() / "far.png"), blank, cv::COLOR_RGB2GRAY);
  ASSERT_EQ(blank.size(), cv::Size(400, 400));
  EXPECT_GT(cv::countNonZero(blank), 0);               // the note
  EXPECT_LT(cv::countNonZero(blank), 400 * 400 / 50);  // and nothing else
}

TEST(RockExtraction, RocklessGroundGivesNoRocks) {
  SceneOptions options;
  options.half_extent_m = 40.0;
  options.crater_count = 0;
  options.roughness_m = 0.3;
  const Scene scene(options);  // No rock path: no rocks.
  SimulatedPointsOptions sim;
  sim.azimuth_max_deg = 90.0;
  sim.max_range_m = 12.0;
  const PointCloud cloud = SimulateSitePointCloud(scene, {0, 0}, 0, sim);
  RockExtractionSummary summary;
  const std::vector<ExtractedRock> rocks = ExtractRocks(cloud, {}, &summary);
  int tall = 0;
  for (const ExtractedRock& e : rocks) tall += e.height_m >= 0.15 ? 1 : 0;
  EXPECT_EQ(tall, 0);
}

// A cone (H 20 cm, base radius 25 cm) on flat ground at elevation 0, 10 m from the camera, both
// with 4 cm of vertical noise (a far rock's range error projected on the vertical); the rock face
// is sampled four times as densely as the ground, as a camera facing it sees it. Fitting the ground
// without the rock's own points (plane_exclusion_k) leaves the plane under the peak near 0, where
// the rock's low flanks, inside the noise-scaled threshold, lift the plane that keeps them.
TEST(RockExtraction, GroundWithoutTheRockIsNotLiftedByItsFlanks) {
  const Eigen::Vector2d centre(10.0, 0.0);
  const double height = 0.20, radius = 0.25, noise = 0.04;
  std::mt19937 rng(7);
  std::normal_distribution<double> gauss(0.0, noise);
  PointCloud cloud;
  cloud.camera_center = Eigen::Vector3d(0, 0, -1.5);
  const auto add = [&](double x, double y, double elevation) {
    StereoPoint p;
    p.position = Eigen::Vector3d(x, y, -(elevation + gauss(rng)));
    p.covariance = Eigen::Vector3d(0.01, 0.01, noise * noise).asDiagonal();
    cloud.points.push_back(p);
  };
  for (double x = -1.2; x <= 1.2; x += 0.02) {
    for (double y = -1.2; y <= 1.2; y += 0.02) {
      if (std::hypot(x, y) > radius) add(centre.x() + x, centre.y() + y, 0.0);
    }
  }
  for (double x = -radius; x <= radius; x += 0.01) {
    for (double y = -radius; y <= radius; y += 0.01) {
      const double r = std::hypot(x, y);
      if (r <= radius) add(centre.x() + x, centre.y() + y, height * (1.0 - r / radius));
    }
  }
  const auto foot_elevation = [&](double k) {
    RockExtractionOptions options;
    options.plane_exclusion_k = k;
    options.fit_models = false;
    double best = 1e9, foot = std::nan("");
    for (const ExtractedRock& rock : ExtractRocks(cloud, options)) {
      const double d = (rock.peak.head<2>() - centre).norm();
      if (d < best) {
        best = d;
        foot = -rock.peak_foot.z();
      }
    }
    EXPECT_LT(best, radius) << "k " << k;
    return foot;
  };
  const double with_flanks = foot_elevation(0.0);
  const double without = foot_elevation(1.0);
  // The mean of ~10 000 ground points has a sigma of 0.04 mm; trimming the upper tail of the
  // noise (2.5 robust sigmas) moves it by at most a few millimetres.
  EXPECT_LT(std::abs(without), 0.005) << "with the flanks: " << with_flanks;
  EXPECT_GT(with_flanks - without, 0.005);
}

TEST(RockExtraction, BadCloudsAreErrorsOrEmpty) {
  PointCloud cloud;
  EXPECT_TRUE(ExtractRocks(cloud, {}).empty());
  cloud.points.resize(10);
  for (int i = 0; i < 10; ++i) cloud.points[i].position = Eigen::Vector3d(i * 0.1, 0, 0);
  // Duplicates only: no relief, no rocks.
  EXPECT_TRUE(ExtractRocks(cloud, {}).empty());
  // A far outlier does not blow up the neighbour grid (it only indexes points near the camera).
  cloud.points[5].position = Eigen::Vector3d(1e9, -1e9, 0.0);
  EXPECT_TRUE(ExtractRocks(cloud, {}).empty());
  // A wild point a million kilometres above the ground near the camera is a peak candidate, but
  // its ground neighbourhood scales with its relief and holds no plane: no rock, no crash (the
  // voxel index's own test covers wild points in the surface search).
  PointCloud wild;
  for (int i = 0; i < 21; ++i) {
    for (int k = 0; k < 21; ++k) {
      StereoPoint p;
      p.position = Eigen::Vector3d(1.5 + 0.05 * i, -0.5 + 0.05 * k, 0.0);
      wild.points.push_back(p);
    }
  }
  wild.points[220].position.z() = -1e9;
  RockExtractionSummary wild_summary;
  EXPECT_TRUE(ExtractRocks(wild, {}, &wild_summary).empty());
  EXPECT_EQ(wild_summary.peak_candidates, 1);
  EXPECT_EQ(wild_summary.too_low, 1);
  cloud.points[3].position.z() = std::nan("");
  EXPECT_THROW(ExtractRocks(cloud, {}), Error);
  RockExtractionOptions bad;
  bad.surface_k_max = 0.1;
  EXPECT_THROW(ExtractRocks(PointCloud{}, bad), Error);
}

}  // namespace
}  // namespace areomap
