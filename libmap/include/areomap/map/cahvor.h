// CAHV and CAHVOR camera models (Yakimovsky & Cunningham 1978; Gennery 2001), as MER and MSL
// products carry them: C, the camera centre [m]; A, the unit pointing axis; H and V, the
// horizontal and vertical image vectors [px]; for CAHVOR also O, the unit optical axis, and
// R = (R0, R1, R2), the radial distortion coefficients.
//
// Frames: the model lives in the frame its label names (e.g. ROVER_FRAME); Transformed() moves
// it to another frame. Pixels: (x, y) = (sample, line), 0-based with the first pixel's centre at
// (0, 0) (JPL's convention; add 0.5 for GDAL pixel coordinates).
//
// Failure: Project() returns std::nullopt for a point behind the camera (on or behind the plane
// through C normal to A); Unproject() always returns a unit ray.
#pragma once

#include <optional>
#include <string>

#include <Eigen/Core>

#include "areomap/map/pds_label.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

struct CahvorModel {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  Eigen::Vector3d a = Eigen::Vector3d::UnitX();
  Eigen::Vector3d h = Eigen::Vector3d::Zero();
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d o = Eigen::Vector3d::UnitX();  // = a for a CAHV model.
  Eigen::Vector3d r = Eigen::Vector3d::Zero();   // Zero for a CAHV model.

  bool HasDistortion() const { return r.squaredNorm() > 0.0; }

  // Projects a point (in the model's frame, [m]) to a pixel. Templated so Ceres can
  // differentiate it: T is double or a ceres::Jet. Returns false for points behind the camera.
  template <typename T>
  bool Project(const Eigen::Matrix<T, 3, 1>& point, Eigen::Matrix<T, 2, 1>* pixel) const;
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point) const;

  // The unit ray (in the model's frame) along which pixel `pixel` sees; starts at c.
  Eigen::Vector3d Unproject(const Eigen::Vector2d& pixel) const;

  // Principal point (hc, vc) and focal lengths (hs, vs) in pixels.
  Eigen::Vector2d PrincipalPoint() const { return {a.dot(h), a.dot(v)}; }
  Eigen::Vector2d FocalLengths() const { return {a.cross(h).norm(), a.cross(v).norm()}; }

  // The same camera expressed in frame b, given b_from_a for its current frame a.
  CahvorModel Transformed(const Rigid3d& b_from_a) const;
};

// Reads a CAHV or CAHVOR model from a product label's GEOMETRIC_CAMERA_MODEL group. Throws
// areomap::Error naming `source` for other model types (CAHVORE is not handled yet) or missing
// components.
CahvorModel CahvorFromLabel(const CameraModelLabel& label, const std::string& source);

template <typename T>
bool CahvorModel::Project(const Eigen::Matrix<T, 3, 1>& point,
                          Eigen::Matrix<T, 2, 1>* pixel) const {
  Eigen::Matrix<T, 3, 1> p = point - c.cast<T>();
  if (HasDistortion()) {
    const T zeta = p.dot(o.cast<T>());
    const Eigen::Matrix<T, 3, 1> lambda = p - zeta * o.cast<T>();
    const T tau = lambda.squaredNorm() / (zeta * zeta);
    const T mu = T(r.x()) + T(r.y()) * tau + T(r.z()) * tau * tau;
    p = p + mu * lambda;
  }
  const T depth = p.dot(a.cast<T>());
  if (!(depth > T(0))) return false;
  (*pixel)(0) = p.dot(h.cast<T>()) / depth;
  (*pixel)(1) = p.dot(v.cast<T>()) / depth;
  return true;
}

}  // namespace areomap
