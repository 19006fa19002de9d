// Rigid transform between two 3D frames: p_in_b = b_from_a * p_in_a.
//
// Naming follows COLMAP: a transform is named `b_from_a`, a point `p_in_b`.
// Composition: c_from_a = c_from_b * b_from_a. Units: metres.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace areomap {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& rotation_b_from_a, const Eigen::Vector3d& translation_in_b)
      : rotation(rotation_b_from_a.normalized()), translation(translation_in_b) {}
  Rigid3d(const Eigen::Matrix3d& rotation_b_from_a, const Eigen::Vector3d& translation_in_b)
      : rotation(Eigen::Quaterniond(rotation_b_from_a).normalized()),
        translation(translation_in_b) {}

  Eigen::Vector3d operator*(const Eigen::Vector3d& p_in_a) const {
    return rotation * p_in_a + translation;
  }
  Rigid3d operator*(const Rigid3d& b_from_a) const {  // (c_from_b * b_from_a) = c_from_a
    return Rigid3d(rotation * b_from_a.rotation, rotation * b_from_a.translation + translation);
  }
  Rigid3d Inverse() const {
    const Eigen::Quaterniond inverse = rotation.conjugate();
    return Rigid3d(inverse, -(inverse * translation));
  }
  Eigen::Matrix3d RotationMatrix() const { return rotation.toRotationMatrix(); }
  Eigen::Matrix<double, 3, 4> ToMatrix() const {
    Eigen::Matrix<double, 3, 4> m;
    m << RotationMatrix(), translation;
    return m;
  }
};

}  // namespace areomap
