// Stereo triangulation and its error model (ch. 4.1, eqs. 4.1-4.3).
//
// Units: metres and pixels; all points, centres and directions in one frame (e.g. the site
// frame). Failure: TriangulateRays returns std::nullopt when the rays are (nearly) parallel or
// the intersection lies behind either camera — Table 4.5's "intersection computable" filter.
#pragma once

#include <optional>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace areomap {

// Eq. 4.3: range error sigma_r = r^2 sigma_p / (b f) [m], with the range r [m], the parallax
// (matching) error sigma_p [px], the stereo base b [m] and the focal length f [px].
double StereoRangeSigma(double range_m, double baseline_m, double focal_px,
                        double parallax_sigma_px);

struct StereoErrorModel {
  double baseline_m = 0.20;        // Navcam (Table 1.1).
  double focal_px = 1222.5;        // Navcam: 14.67 mm on 12 um pixels.
  double parallax_sigma_px = 0.5;  // sigma_p of eq. 4.3.
  double azimuth_sigma_px = 1.0;   // sigma_theta as pixels (ch. 4.1: about one pixel).
  void Check() const;              // Throws areomap::Error naming the field.
};

// Covariance [m^2] of a stereo point seen from `camera_center`: sigma_r (eq. 4.3) along the
// line of sight and r * azimuth_sigma_px / f across it, horizontally and vertically. Its
// horizontal block is eq. 4.2 for a horizontal line of sight.
Eigen::Matrix3d StereoPointCovariance(const Eigen::Vector3d& point,
                                      const Eigen::Vector3d& camera_center,
                                      const StereoErrorModel& model);

struct RayIntersection {
  Eigen::Vector3d point;       // Midpoint of the shortest segment between the rays.
  double gap_m = 0.0;          // Length of that segment (a matching-quality check).
  double range_first_m = 0.0;  // Distance from the first centre to the point.
};

// Intersects ray c1 + s d1 with c2 + t d2 (directions need not be unit).
std::optional<RayIntersection> TriangulateRays(const Eigen::Vector3d& c1, const Eigen::Vector3d& d1,
                                               const Eigen::Vector3d& c2,
                                               const Eigen::Vector3d& d2);

}  // namespace areomap
