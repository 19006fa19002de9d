// CAHV, CAHVOR and CAHVORE camera models (Yakimovsky & Cunningham 1978; Gennery 2001, 2006), as
// MER and MSL products carry them: C, the camera centre [m]; A, the unit pointing axis; H and V,
// the horizontal and vertical image vectors [px]; for CAHVOR also O, the unit optical axis, and
// R = (R0, R1, R2), the radial distortion coefficients; for CAHVORE also E = (E0, E1, E2), the
// entrance-pupil movement [m], and the linearity (type T and parameter P) of the fish-eye part.
//
// Frames: the model lives in the frame its label names (e.g. ROVER_FRAME); Transformed() moves
// it to another frame. Pixels: (x, y) = (sample, line), 0-based with the first pixel's centre at
// (0, 0) (JPL's convention; add 0.5 for GDAL pixel coordinates).
//
// Failure: Project() returns std::nullopt for a point behind the camera (on or behind the plane
// through C normal to A) or, for CAHVORE, outside the model's domain; Unproject() always returns
// a unit ray.
#pragma once

#include <cmath>
#include <numbers>
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
// areomap::Error naming `source` for other model types (CAHVORE: CahvoreFromLabel) or missing
// components.
CahvorModel CahvorFromLabel(const CameraModelLabel& label, const std::string& source);

// A ray in a model's frame: origin [m] and unit direction.
struct CameraRay {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
};

// CAHVORE (Gennery 2006; JPL's cmod_cahvore): CAHVOR plus a moving entrance pupil for wide-angle
// and fish-eye lenses. A ray at angle theta from O enters through the pupil point
// C + s(theta) O, s = (theta / sin(theta) - 1)(E0 + E1 theta^2 + E2 theta^4); the angle maps to
// the "perspective" tangent chi by the linearity L: chi = tan(L theta) / L for L > 0, theta for
// L = 0, sin(L theta) / L for L < 0; then CAHVOR's radial distortion applies to chi.
// Type T = 1 is perspective (L = 1), 2 fish-eye (L = 0), 3 general (L = P).
struct CahvoreModel {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  Eigen::Vector3d a = Eigen::Vector3d::UnitX();
  Eigen::Vector3d h = Eigen::Vector3d::Zero();
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d o = Eigen::Vector3d::UnitX();
  Eigen::Vector3d r = Eigen::Vector3d::Zero();
  Eigen::Vector3d e = Eigen::Vector3d::Zero();  // [m]
  int type = 1;                                 // T: 1 perspective, 2 fish-eye, 3 general.
  double parameter = 0.0;                       // P: the linearity when type == 3.

  double Linearity() const { return type == 1 ? 1.0 : type == 2 ? 0.0 : parameter; }

  // As CahvorModel::Project, templated for Ceres. Solves for the ray angle theta by Newton's
  // method (converged to 1e-12 rad). Returns false behind the camera or where L theta >= pi/2.
  template <typename T>
  bool Project(const Eigen::Matrix<T, 3, 1>& point, Eigen::Matrix<T, 2, 1>* pixel) const;
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point) const;

  // The ray pixel `pixel` sees: it starts at the entrance pupil point, not at c.
  CameraRay Unproject(const Eigen::Vector2d& pixel) const;

  Eigen::Vector2d PrincipalPoint() const { return {a.dot(h), a.dot(v)}; }
  Eigen::Vector2d FocalLengths() const { return {a.cross(h).norm(), a.cross(v).norm()}; }
  CahvoreModel Transformed(const Rigid3d& b_from_a) const;
};

// Reads a CAHVORE model (components C A H V O R E T P; T in 1..3). Throws areomap::Error naming
// `source` and the component for another model type, a missing component or a bad T.
CahvoreModel CahvoreFromLabel(const CameraModelLabel& label, const std::string& source);

template <typename T>
bool CahvoreModel::Project(const Eigen::Matrix<T, 3, 1>& point,
                           Eigen::Matrix<T, 2, 1>* pixel) const {
  using std::abs;
  using std::atan2;
  using std::cos;
  using std::sin;
  using std::sqrt;
  using std::tan;
  const Eigen::Matrix<T, 3, 1> p = point - c.cast<T>();
  const T zeta = p.dot(o.cast<T>());
  const Eigen::Matrix<T, 3, 1> lambda = p - zeta * o.cast<T>();
  const T lambda2 = lambda.squaredNorm();
  Eigen::Matrix<T, 3, 1> rp = p;
  if (lambda2 > T(1e-24) * (zeta * zeta + T(1e-300))) {
    const T lam = sqrt(lambda2);
    // Solve zeta sin(theta) - lam cos(theta) - (theta - sin(theta)) E(theta) = 0, the condition
    // that the ray from the pupil point C + s(theta) O at angle theta passes through the point.
    T theta = atan2(lam, zeta);
    for (int i = 0; i < 100; ++i) {
      const T s = sin(theta), co = cos(theta), t2 = theta * theta;
      const T e_poly = T(e.x()) + T(e.y()) * t2 + T(e.z()) * t2 * t2;
      const T f = zeta * s - lam * co - (theta - s) * e_poly;
      const T df = zeta * co + lam * s - (T(1.0) - co) * e_poly -
                   (theta - s) * (T(2.0 * e.y()) * theta + T(4.0 * e.z()) * t2 * theta);
      if (!(abs(df) > T(1e-300))) return false;
      const T step = f / df;
      theta = theta - step;
      if (abs(step) < T(1e-13)) break;
    }
    const double linearity = Linearity();
    if (!(theta > T(0)) || theta * T(std::abs(linearity)) >= T(std::numbers::pi / 2.0))
      return false;
    T chi;
    if (linearity > 1e-15) {
      chi = tan(T(linearity) * theta) / T(linearity);
    } else if (linearity < -1e-15) {
      chi = sin(T(linearity) * theta) / T(linearity);
    } else {
      chi = theta;
    }
    const T chi2 = chi * chi;
    const T mu = T(r.x()) + T(r.y()) * chi2 + T(r.z()) * chi2 * chi2;
    rp = (lam / chi) * o.cast<T>() + (T(1.0) + mu) * lambda;
  }
  const T depth = rp.dot(a.cast<T>());
  if (!(depth > T(0))) return false;
  (*pixel)(0) = rp.dot(h.cast<T>()) / depth;
  (*pixel)(1) = rp.dot(v.cast<T>()) / depth;
  return true;
}

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
