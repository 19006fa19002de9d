// Ceres residuals of the bundle adjustment (private). Every residual is whitened: r = W (pred -
// obs) with W = L^-1 for the observation covariance C = L L^T, so |r|^2 is the Mahalanobis
// distance. Pose blocks are [rotation vector (3), translation (3)] of traverse_from_site.
#pragma once

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "areomap/map/cahvor.h"
#include "areomap/map/error.h"
#include "areomap/map/rigid3d.h"

namespace areomap::bundle_internal {

// W with W C W^T = I for a symmetric positive definite C. Throws Error(`what` ...) otherwise.
template <int N>
Eigen::Matrix<double, N, N> Whitening(const Eigen::Matrix<double, N, N>& covariance,
                                      const std::string& what) {
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(covariance);
  if (llt.info() != Eigen::Success || !covariance.allFinite()) {
    throw Error(what + ": covariance is not symmetric positive definite");
  }
  const Eigen::Matrix<double, N, N> l = llt.matrixL();
  return l.inverse();
}

// A landmark measured by stereo in a site frame: pred = site_from_traverse * X.
struct StereoPointResidual {
  Eigen::Vector3d observed;
  Eigen::Matrix3d whitening;
  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    const T minus_rotation[3] = {-pose[0], -pose[1], -pose[2]};
    const T relative[3] = {point[0] - pose[3], point[1] - pose[4], point[2] - pose[5]};
    T predicted[3];
    ceres::AngleAxisRotatePoint(minus_rotation, relative, predicted);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    const Eigen::Matrix<T, 3, 1> error(predicted[0] - T(observed.x()),
                                       predicted[1] - T(observed.y()),
                                       predicted[2] - T(observed.z()));
    r = whitening.cast<T>() * error;
    return true;
  }
};

// A landmark seen in an image: pixel = camera.Project(site_from_traverse * X), CAHVOR model in
// the site frame. Points behind the camera make the residual fail (Ceres then shortens the step).
struct ImageResidual {
  CahvorModel camera;
  Eigen::Vector2d observed;
  double sigma_px = 0.5;
  template <typename T>
  bool operator()(const T* pose, const T* point, T* residual) const {
    const T minus_rotation[3] = {-pose[0], -pose[1], -pose[2]};
    const T relative[3] = {point[0] - pose[3], point[1] - pose[4], point[2] - pose[5]};
    Eigen::Matrix<T, 3, 1> in_site;
    ceres::AngleAxisRotatePoint(minus_rotation, relative, in_site.data());
    Eigen::Matrix<T, 2, 1> pixel;
    if (!camera.Project(in_site, &pixel)) return false;
    residual[0] = (pixel.x() - T(observed.x())) / T(sigma_px);
    residual[1] = (pixel.y() - T(observed.y())) / T(sigma_px);
    return true;
  }
};

// A landmark position known in the traverse frame (an orbital control point).
struct AbsolutePointResidual {
  Eigen::Vector3d observed;
  Eigen::Matrix3d whitening;
  template <typename T>
  bool operator()(const T* point, T* residual) const {
    Eigen::Map<Eigen::Matrix<T, 3, 1>> r(residual);
    const Eigen::Matrix<T, 3, 1> error(point[0] - T(observed.x()), point[1] - T(observed.y()),
                                       point[2] - T(observed.z()));
    r = whitening.cast<T>() * error;
    return true;
  }
};

// Residual of a pose a_from_b = (q, t) against a measured one (q_m, t_m):
// [Log(q_m^-1 q); t - t_m], whitened.
template <typename T>
void PoseError(const T* q, const T* t, const Eigen::Quaterniond& measured_rotation,
               const Eigen::Vector3d& measured_translation, T* error) {
  const T q_m_inverse[4] = {T(measured_rotation.w()), T(-measured_rotation.x()),
                            T(-measured_rotation.y()), T(-measured_rotation.z())};
  T q_error[4];
  ceres::QuaternionProduct(q_m_inverse, q, q_error);
  if (q_error[0] < T(0)) {
    for (T& c : q_error) c = -c;
  }
  ceres::QuaternionToAngleAxis(q_error, error);
  for (int i = 0; i < 3; ++i) error[3 + i] = t[i] - T(measured_translation[i]);
}

// Relative pose prior between two sites: a_from_b = traverse_from_a^-1 * traverse_from_b.
struct RelativePoseResidual {
  Rigid3d a_from_b;
  Eigen::Matrix<double, 6, 6> whitening;
  template <typename T>
  bool operator()(const T* pose_a, const T* pose_b, T* residual) const {
    T q_a[4], q_b[4];
    ceres::AngleAxisToQuaternion(pose_a, q_a);
    ceres::AngleAxisToQuaternion(pose_b, q_b);
    const T q_a_inverse[4] = {q_a[0], -q_a[1], -q_a[2], -q_a[3]};
    T q[4];
    ceres::QuaternionProduct(q_a_inverse, q_b, q);
    const T delta[3] = {pose_b[3] - pose_a[3], pose_b[4] - pose_a[4], pose_b[5] - pose_a[5]};
    T t[3];
    ceres::UnitQuaternionRotatePoint(q_a_inverse, delta, t);
    T error[6];
    PoseError(q, t, a_from_b.rotation, a_from_b.translation, error);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r = whitening.cast<T>() * Eigen::Map<const Eigen::Matrix<T, 6, 1>>(error);
    return true;
  }
};

// Prior on one site's traverse_from_site.
struct AbsolutePoseResidual {
  Rigid3d traverse_from_site;
  Eigen::Matrix<double, 6, 6> whitening;
  template <typename T>
  bool operator()(const T* pose, T* residual) const {
    T q[4];
    ceres::AngleAxisToQuaternion(pose, q);
    T error[6];
    PoseError(q, pose + 3, traverse_from_site.rotation, traverse_from_site.translation, error);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
    r = whitening.cast<T>() * Eigen::Map<const Eigen::Matrix<T, 6, 1>>(error);
    return true;
  }
};

// Height of a site origin above the ellipsoid, linearized at t0 (traverse frame):
// h(t) = h0 + up . (t - t0); the second-order term is |t - t0|^2 / R (millimetres here).
struct HeightResidual {
  double h0 = 0.0;
  Eigen::Vector3d t0;
  Eigen::Vector3d up;  // Ellipsoid normal (up) at t0, traverse frame.
  double observed = 0.0;
  double sigma = 1.0;
  template <typename T>
  bool operator()(const T* pose, T* residual) const {
    T h = T(h0);
    for (int i = 0; i < 3; ++i) h += T(up[i]) * (pose[3 + i] - T(t0[i]));
    residual[0] = (h - T(observed)) / T(sigma);
    return true;
  }
};

}  // namespace areomap::bundle_internal
