#include "areomap/map/cahvor.h"

#include <cmath>

#include "areomap/map/error.h"

namespace areomap {

std::optional<Eigen::Vector2d> CahvorModel::Project(const Eigen::Vector3d& point) const {
  Eigen::Vector2d pixel;
  if (!Project<double>(point, &pixel)) return std::nullopt;
  return pixel;
}

Eigen::Vector3d CahvorModel::Unproject(const Eigen::Vector2d& pixel) const {
  // CAHV ray: the intersection of the planes through C of constant x and constant y.
  Eigen::Vector3d ray = (v - pixel.y() * a).cross(h - pixel.x() * a);
  if (ray.dot(a) < 0.0) ray = -ray;
  ray.normalize();
  if (!HasDistortion()) return ray;
  // Undo the radial distortion (Gennery 2001): with k = |lambda| / zeta of the undistorted ray
  // and k' that of the distorted one, k (1 + R0 + R1 k^2 + R2 k^4) = k'. Newton from k = k'.
  const double zeta = ray.dot(o);
  const Eigen::Vector3d lambda = ray - zeta * o;
  const double k_distorted = lambda.norm() / zeta;
  if (k_distorted < 1e-15) return ray;
  double k = k_distorted;
  for (int i = 0; i < 20; ++i) {
    const double k2 = k * k;
    const double f = k * (1.0 + r.x() + r.y() * k2 + r.z() * k2 * k2) - k_distorted;
    const double df = 1.0 + r.x() + 3.0 * r.y() * k2 + 5.0 * r.z() * k2 * k2;
    const double step = f / df;
    k -= step;
    if (std::abs(step) < 1e-15) break;
  }
  return (zeta * o + (k / k_distorted) * lambda).normalized();
}

CahvorModel CahvorModel::Transformed(const Rigid3d& b_from_a) const {
  CahvorModel out = *this;
  const Eigen::Matrix3d rotation = b_from_a.RotationMatrix();
  out.c = b_from_a * c;
  out.a = rotation * a;
  out.h = rotation * h;
  out.v = rotation * v;
  out.o = rotation * o;
  return out;
}

CahvorModel CahvorFromLabel(const CameraModelLabel& label, const std::string& source) {
  if (label.model_type != "CAHV" && label.model_type != "CAHVOR") {
    throw Error(source + ": camera model type " + label.model_type +
                " is not supported here: expected CAHV or CAHVOR");
  }
  const auto vector = [&](const char* id) {
    const auto it = label.components.find(id);
    if (it == label.components.end() || it->second.size() != 3) {
      throw Error(source + ": GEOMETRIC_CAMERA_MODEL component " + id +
                  " is missing: expected 3 numbers");
    }
    return Eigen::Vector3d(it->second[0], it->second[1], it->second[2]);
  };
  CahvorModel model;
  model.c = vector("C");
  model.a = vector("A");
  model.h = vector("H");
  model.v = vector("V");
  model.o = model.a;
  if (label.model_type == "CAHVOR") {
    model.o = vector("O");
    model.r = vector("R");
  }
  if (std::abs(model.a.norm() - 1.0) > 1e-3 || std::abs(model.o.norm() - 1.0) > 1e-3) {
    throw Error(source + ": camera model A or O is not a unit vector");
  }
  return model;
}

}  // namespace areomap
