// Stereo point clouds simulated straight from the scene's truth, for testing consumers of
// PointCloud (DTM gridding, rock extraction, tie points) without rendering and matching images.
//
// Geometry: the camera sits `camera_height_m` above the ground at an ENU position; points are laid
// out like a pixel grid seen from it (one point per `angular_step_rad` in azimuth and in depression
// angle), only where the line of sight reaches the ground (a viewshed along each azimuth hides
// what lies behind rocks and ridges), between `min_range_m` and `max_range_m`. Each true point is
// displaced by a draw from its eq. 4.1-4.3 covariance (StereoPointCovariance) unless `noise` is
// false. Output frame: the site frame (x north, y east, z down [m]) with its origin on the ground
// below `camera_enu`, i.e. SiteFromEnu() applied after subtracting the site origin.
#pragma once

#include <cstdint>

#include <Eigen/Core>

#include "areomap/map/point_cloud.h"
#include "areomap/map/stereo_error.h"
#include "areomap/samples/scene.h"

namespace areomap {

struct SimulatedPointsOptions {
  double camera_height_m = 1.5;  // Mast height above the ground [m].
  double azimuth_min_deg = 0.0;  // Clockwise from north [deg]; 0..360 is a full panorama.
  double azimuth_max_deg = 360.0;
  double angular_step_rad = 4e-3;  // Sampling of azimuth and depression angle.
  double min_range_m = 2.0;        // Horizontal distance limits [m].
  double max_range_m = 30.0;
  StereoErrorModel stereo;  // Navcam by default.
  bool noise = true;
  uint32_t seed = 1;
  void Check() const;  // Throws areomap::Error naming the field.
};

// Throws areomap::Error for invalid options. Deterministic for a given seed.
PointCloud SimulateSitePointCloud(const Scene& scene, const Eigen::Vector2d& site_enu, int site,
                                  const SimulatedPointsOptions& options);

}  // namespace areomap
