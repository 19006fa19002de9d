#include "areomap/samples/simulated_points.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include <Eigen/Cholesky>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"

namespace areomap {

void SimulatedPointsOptions::Check() const {
  RequireOption(camera_height_m > 0.0, "camera_height_m", "a positive height in metres");
  RequireOption(azimuth_max_deg > azimuth_min_deg && azimuth_max_deg - azimuth_min_deg <= 360.0,
                "azimuth_max_deg", "greater than azimuth_min_deg, at most 360 degrees more");
  RequireOption(angular_step_rad > 0.0 && angular_step_rad < 0.1, "angular_step_rad",
                "between 0 and 0.1 rad");
  RequireOption(min_range_m > 0.0 && max_range_m > min_range_m, "max_range_m",
                "0 < min_range_m < max_range_m");
  stereo.Check();
}

namespace {

// Draws x ~ N(0, covariance) with a seeded generator (LLT of the 3x3 covariance).
Eigen::Vector3d DrawGaussian(const Eigen::Matrix3d& covariance, std::mt19937& rng) {
  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::Vector3d unit(normal(rng), normal(rng), normal(rng));
  return covariance.llt().matrixL() * unit;
}

}  // namespace

PointCloud SimulateSitePointCloud(const Scene& scene, const Eigen::Vector2d& site_enu, int site,
                                  const SimulatedPointsOptions& options) {
  options.Check();
  const double ground_z = scene.GroundHeightAt(site_enu.x(), site_enu.y());
  const Eigen::Vector3d site_origin_enu(site_enu.x(), site_enu.y(), ground_z);
  const Eigen::Vector3d camera_enu =
      site_origin_enu + Eigen::Vector3d(0, 0, options.camera_height_m);
  const Rigid3d site_from_enu = SiteFromEnu();

  PointCloud cloud;
  cloud.frame = "SITE_FRAME site " + std::to_string(site);
  cloud.site = site;
  cloud.camera_center = site_from_enu * (camera_enu - site_origin_enu);
  std::mt19937 rng(options.seed);

  const double step = options.angular_step_rad;
  const double az_min = options.azimuth_min_deg * std::numbers::pi / 180.0;
  const double az_max = options.azimuth_max_deg * std::numbers::pi / 180.0;
  const int azimuth_count = static_cast<int>(std::floor((az_max - az_min) / step));
  for (int ia = 0; ia < azimuth_count; ++ia) {
    const double azimuth = az_min + (ia + 0.5) * step;
    const Eigen::Vector2d dir(std::sin(azimuth), std::cos(azimuth));  // ENU, clockwise from N.
    // Walk outward in small horizontal steps, tracking the highest elevation angle seen; a
    // sample is visible when nothing nearer rises above its line of sight.
    double horizon = -std::numeric_limits<double>::infinity();
    double next_depression = std::atan2(options.camera_height_m, options.min_range_m);
    for (double r = 0.2; r <= options.max_range_m; r += 0.01 + 0.002 * r) {
      const Eigen::Vector2d xy = site_enu + r * dir;
      const double z = scene.HeightAt(xy.x(), xy.y());
      const double elevation = std::atan2(z - camera_enu.z(), r);
      const bool visible = elevation >= horizon;
      horizon = std::max(horizon, elevation);
      if (r < options.min_range_m || !visible || -elevation > next_depression) continue;
      // One point per angular step in depression angle, like consecutive image rows.
      next_depression = -elevation - step;
      const Eigen::Vector3d truth_site =
          site_from_enu * (Eigen::Vector3d(xy.x(), xy.y(), z) - site_origin_enu);
      StereoPoint point;
      point.covariance = StereoPointCovariance(truth_site, cloud.camera_center, options.stereo);
      point.position =
          options.noise ? truth_site + DrawGaussian(point.covariance, rng) : truth_site;
      point.intensity = static_cast<float>(scene.AlbedoAt(xy.x(), xy.y()));
      point.left_x = static_cast<float>(ia);
      point.left_y = static_cast<float>(next_depression / step);
      cloud.points.push_back(point);
    }
  }
  return cloud;
}

}  // namespace areomap
