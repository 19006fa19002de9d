#include "areomap/map/stereo_error.h"

#include <cmath>

#include "areomap/map/error.h"

namespace areomap {

double StereoRangeSigma(double range_m, double baseline_m, double focal_px,
                        double parallax_sigma_px) {
  return range_m * range_m * parallax_sigma_px / (baseline_m * focal_px);
}

void StereoErrorModel::Check() const {
  RequireOption(baseline_m > 0.0, "StereoErrorModel.baseline_m", "> 0 m");
  RequireOption(focal_px > 0.0, "StereoErrorModel.focal_px", "> 0 px");
  RequireOption(parallax_sigma_px >= 0.0, "StereoErrorModel.parallax_sigma_px", ">= 0 px");
  RequireOption(azimuth_sigma_px >= 0.0, "StereoErrorModel.azimuth_sigma_px", ">= 0 px");
}

Eigen::Matrix3d StereoPointCovariance(const Eigen::Vector3d& point,
                                      const Eigen::Vector3d& camera_center,
                                      const StereoErrorModel& model) {
  const Eigen::Vector3d line = point - camera_center;
  const double range = line.norm();
  if (!(range > 0.0)) return Eigen::Matrix3d::Zero();
  const Eigen::Vector3d along = line / range;
  // Across-track axes: one in the plane perpendicular to the vertical (z), one completing.
  Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(along);
  if (across.norm() < 1e-9) across = Eigen::Vector3d::UnitX().cross(along);
  across.normalize();
  const Eigen::Vector3d third = along.cross(across);
  const double sigma_r =
      StereoRangeSigma(range, model.baseline_m, model.focal_px, model.parallax_sigma_px);
  const double sigma_t = range * model.azimuth_sigma_px / model.focal_px;
  return sigma_r * sigma_r * along * along.transpose() +
         sigma_t * sigma_t * (across * across.transpose() + third * third.transpose());
}

std::optional<RayIntersection> TriangulateRays(const Eigen::Vector3d& c1, const Eigen::Vector3d& d1,
                                               const Eigen::Vector3d& c2,
                                               const Eigen::Vector3d& d2) {
  const Eigen::Vector3d u = d1.normalized(), v = d2.normalized();
  const Eigen::Vector3d w = c1 - c2;
  const double b = u.dot(v);
  const double denominator = 1.0 - b * b;
  if (denominator < 1e-12) return std::nullopt;  // Parallel rays.
  const double s = (b * v.dot(w) - u.dot(w)) / denominator;
  const double t = (v.dot(w) - b * u.dot(w)) / denominator;
  if (s <= 0.0 || t <= 0.0) return std::nullopt;  // Behind a camera.
  const Eigen::Vector3d p1 = c1 + s * u, p2 = c2 + t * v;
  return RayIntersection{0.5 * (p1 + p2), (p1 - p2).norm(), (0.5 * (p1 + p2) - c1).norm()};
}

}  // namespace areomap
