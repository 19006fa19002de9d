#include "areomap/map/cahvor.h"

#include <algorithm>
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

namespace {

// C moves as a point; A, H, V and O rotate. R and E are coefficients, not directions.
template <typename Model>
Model TransformedCahvorFamily(const Model& model, const Rigid3d& b_from_a) {
  Model out = model;
  const Eigen::Matrix3d rotation = b_from_a.RotationMatrix();
  out.c = b_from_a * model.c;
  out.a = rotation * model.a;
  out.h = rotation * model.h;
  out.v = rotation * model.v;
  out.o = rotation * model.o;
  return out;
}

}  // namespace

CahvorModel CahvorModel::Transformed(const Rigid3d& b_from_a) const {
  return TransformedCahvorFamily(*this, b_from_a);
}

namespace {

Eigen::Vector3d LabelVector(const CameraModelLabel& label, const char* id,
                            const std::string& source) {
  const auto it = label.components.find(id);
  if (it == label.components.end() || it->second.size() != 3) {
    throw Error(source + ": GEOMETRIC_CAMERA_MODEL component " + id +
                " is missing: expected 3 numbers");
  }
  return Eigen::Vector3d(it->second[0], it->second[1], it->second[2]);
}

double LabelScalar(const CameraModelLabel& label, const char* id, const std::string& source) {
  const auto it = label.components.find(id);
  if (it == label.components.end() || it->second.size() != 1) {
    throw Error(source + ": GEOMETRIC_CAMERA_MODEL component " + id +
                " is missing: expected 1 number");
  }
  return it->second[0];
}

}  // namespace

CahvorModel CahvorFromLabel(const CameraModelLabel& label, const std::string& source) {
  if (label.model_type != "CAHV" && label.model_type != "CAHVOR") {
    throw Error(source + ": camera model type " + label.model_type +
                " is not supported here: expected CAHV or CAHVOR (CAHVORE has its own reader)");
  }
  const auto vector = [&](const char* id) { return LabelVector(label, id, source); };
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

std::optional<Eigen::Vector2d> CahvoreModel::Project(const Eigen::Vector3d& point) const {
  Eigen::Vector2d pixel;
  if (!Project<double>(point, &pixel)) return std::nullopt;
  return pixel;
}

CameraRay CahvoreModel::Unproject(const Eigen::Vector2d& pixel) const {
  // The CAHV ray of the pixel, scaled so that rp . a = 1.
  const Eigen::Vector3d rp = (h - pixel.x() * a).cross(v - pixel.y() * a) / a.dot(h.cross(v));
  const double zetap = rp.dot(o);
  const Eigen::Vector3d lambdap = rp - zetap * o;
  const double chip = lambdap.norm() / zetap;
  CameraRay ray;
  if (!(chip > 1e-12)) {
    ray.origin = c;
    ray.direction = o;
    return ray;
  }
  // Undo the radial distortion: chi (1 + R0 + R1 chi^2 + R2 chi^4) = chip.
  double chi = chip;
  for (int i = 0; i < 100; ++i) {
    const double chi2 = chi * chi;
    const double f = chi * (1.0 + r.x() + r.y() * chi2 + r.z() * chi2 * chi2) - chip;
    const double df = 1.0 + r.x() + 3.0 * r.y() * chi2 + 5.0 * r.z() * chi2 * chi2;
    const double step = f / df;
    chi -= step;
    if (std::abs(step) < 1e-15) break;
  }
  const double linearity = Linearity();
  double theta = chi;
  if (linearity > 1e-15) {
    theta = std::atan(linearity * chi) / linearity;
  } else if (linearity < -1e-15) {
    theta = std::asin(std::clamp(linearity * chi, -1.0, 1.0)) / linearity;
  }
  const double theta2 = theta * theta;
  const double shift =
      (theta / std::sin(theta) - 1.0) * (e.x() + e.y() * theta2 + e.z() * theta2 * theta2);
  ray.origin = c + shift * o;
  ray.direction = (std::sin(theta) * lambdap.normalized() + std::cos(theta) * o).normalized();
  return ray;
}

CahvoreModel CahvoreModel::Transformed(const Rigid3d& b_from_a) const {
  return TransformedCahvorFamily(*this, b_from_a);
}

CahvoreModel CahvoreFromLabel(const CameraModelLabel& label, const std::string& source) {
  if (label.model_type != "CAHVORE") {
    throw Error(source + ": camera model type " + label.model_type + " is not CAHVORE");
  }
  CahvoreModel model;
  model.c = LabelVector(label, "C", source);
  model.a = LabelVector(label, "A", source);
  model.h = LabelVector(label, "H", source);
  model.v = LabelVector(label, "V", source);
  model.o = LabelVector(label, "O", source);
  model.r = LabelVector(label, "R", source);
  model.e = LabelVector(label, "E", source);
  const double type = LabelScalar(label, "T", source);
  if (type != 1.0 && type != 2.0 && type != 3.0) {
    throw Error(source + ": GEOMETRIC_CAMERA_MODEL component T (MTYPE) is " + std::to_string(type) +
                ": expected 1 (perspective), 2 (fish-eye) or 3 (general)");
  }
  model.type = static_cast<int>(type);
  model.parameter = LabelScalar(label, "P", source);
  if (std::abs(model.a.norm() - 1.0) > 1e-3 || std::abs(model.o.norm() - 1.0) > 1e-3) {
    throw Error(source + ": camera model A or O is not a unit vector");
  }
  return model;
}

}  // namespace areomap
