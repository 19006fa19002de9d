// Pinhole camera with Brown–Conrady lens distortion, as Ames Stereo Pipeline's `.tsai` files
// (TSAI distortion k1 k2 p1 p2) and OpenCV's calibration describe it.
//
// Frames: `center` [m] and `world_from_camera` place the camera in its world frame (for the K10
// files, the rover frame: x forward, y right, z down). Camera frame axes are given by the u, v, w
// directions (normally x right, y down, z forward). Pixels: (column, row), the first pixel's
// centre at (0, 0) (VisionWorkbench's convention, the same as JPL's for CAHV).
//
// Distortion maps normalized undistorted (x, y) to distorted coordinates (OpenCV's model with
// k3 = 0): r^2 = x^2 + y^2, x_d = x (1 + k1 r^2 + k2 r^4) + 2 p1 x y + p2 (r^2 + 2 x^2),
// y_d = y (1 + k1 r^2 + k2 r^4) + p1 (r^2 + 2 y^2) + 2 p2 x y; pixel = (fu x_d + cu, fv y_d + cv).
//
// Failure: Project() returns false / std::nullopt for points on or behind the image plane.
// ReadTsai throws areomap::Error naming the file and the missing or malformed key.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "areomap/map/cahvor.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

struct PinholeModel {
  double fu = 1.0, fv = 1.0;  // Focal lengths [px] (ASP: in pitch units; pitch 1 = pixels).
  double cu = 0.0, cv = 0.0;  // Principal point [px].
  Eigen::Vector3d u_direction = Eigen::Vector3d::UnitX();
  Eigen::Vector3d v_direction = Eigen::Vector3d::UnitY();
  Eigen::Vector3d w_direction = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d center = Eigen::Vector3d::Zero();                 // C [m] in the world frame.
  Eigen::Matrix3d world_from_camera = Eigen::Matrix3d::Identity();  // R of the .tsai file.
  double k1 = 0.0, k2 = 0.0, p1 = 0.0, p2 = 0.0;
  double pitch = 1.0;  // Pixel pitch in the units of fu, fv, cu, cv.

  template <typename T>
  bool Project(const Eigen::Matrix<T, 3, 1>& point, Eigen::Matrix<T, 2, 1>* pixel) const;
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point) const;

  // The unit ray from `center` that `pixel` sees, in the world frame. The distortion is inverted
  // by Newton's method to 1e-12 in normalized coordinates.
  CameraRay Unproject(const Eigen::Vector2d& pixel) const;

  PinholeModel Transformed(const Rigid3d& b_from_a) const;
};

// Reads / writes ASP's `.tsai` text format (keys fu fv cu cv u_direction v_direction w_direction
// C R k1 k2 p1 p2 [pitch], optionally preceded by VERSION_n and PINHOLE lines and a TSAI line).
// Throws areomap::Error naming the file (`source` for the stream overload), the line or the key.
PinholeModel ReadTsai(const std::filesystem::path& path);
PinholeModel ReadTsai(std::istream& in, const std::string& source);
std::string FormatTsai(const PinholeModel& model);
void WriteTsai(const PinholeModel& model, const std::filesystem::path& path);  // Atomic.

template <typename T>
bool PinholeModel::Project(const Eigen::Matrix<T, 3, 1>& point,
                           Eigen::Matrix<T, 2, 1>* pixel) const {
  const Eigen::Matrix<T, 3, 1> in_camera =
      world_from_camera.transpose().cast<T>() * (point - center.cast<T>());
  const T depth = in_camera.dot(w_direction.cast<T>());
  if (!(depth > T(0))) return false;
  const T x = in_camera.dot(u_direction.cast<T>()) / depth;
  const T y = in_camera.dot(v_direction.cast<T>()) / depth;
  const T r2 = x * x + y * y;
  const T radial = T(1.0) + T(k1) * r2 + T(k2) * r2 * r2;
  const T xd = x * radial + T(2.0 * p1) * x * y + T(p2) * (r2 + T(2.0) * x * x);
  const T yd = y * radial + T(p1) * (r2 + T(2.0) * y * y) + T(2.0 * p2) * x * y;
  (*pixel)(0) = (T(fu) * xd + T(cu)) / T(pitch);
  (*pixel)(1) = (T(fv) * yd + T(cv)) / T(pitch);
  return true;
}

}  // namespace areomap
