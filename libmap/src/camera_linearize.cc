#include "areomap/map/camera_linearize.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <variant>

#include "areomap/map/error.h"

namespace areomap {
namespace {

// The model's own image "down" axis, as JPL's A x H (for a pinhole, the camera's v axis).
Eigen::Vector3d ImageDownAxis(const CameraModel& model) {
  if (const auto* p = std::get_if<PinholeModel>(&model.variant())) {
    return (p->world_from_camera * p->v_direction).normalized();
  }
  if (const auto* m = std::get_if<CahvorModel>(&model.variant())) {
    return m->a.cross(m->h).normalized();
  }
  const auto& m = std::get<CahvoreModel>(model.variant());
  return m.a.cross(m.h).normalized();
}

}  // namespace

CahvorModel LinearizeToCahv(const CameraModel& model, const Eigen::Vector2i& input_size,
                            const Eigen::Vector2i& output_size) {
  RequireOption(input_size.minCoeff() > 0, "LinearizeToCahv input_size", "positive width, height");
  RequireOption(output_size.minCoeff() > 0, "LinearizeToCahv output_size",
                "positive width, height");
  const double w = input_size.x() - 1.0, h = input_size.y() - 1.0;
  CahvorModel out;
  out.c = model.Center();
  out.a = model.Unproject({w / 2.0, h / 2.0}).direction;
  const Eigen::Vector3d right = ImageDownAxis(model).cross(out.a).normalized();
  const Eigen::Vector3d down = out.a.cross(right).normalized();

  // Landmarks: corners and edge midpoints of the left/right (top/bottom) borders.
  const std::array<Eigen::Vector2d, 6> horizontal = {
      Eigen::Vector2d(0, 0), Eigen::Vector2d(0, h / 2), Eigen::Vector2d(0, h),
      Eigen::Vector2d(w, 0), Eigen::Vector2d(w, h / 2), Eigen::Vector2d(w, h)};
  const std::array<Eigen::Vector2d, 6> vertical = {
      Eigen::Vector2d(0, 0), Eigen::Vector2d(w / 2, 0), Eigen::Vector2d(w, 0),
      Eigen::Vector2d(0, h), Eigen::Vector2d(w / 2, h), Eigen::Vector2d(w, h)};
  // The largest cosine (smallest angle) to the axis, within the plane of the axis and `in_plane`.
  const auto max_cosine = [&](const std::array<Eigen::Vector2d, 6>& pixels,
                              const Eigen::Vector3d& normal) {
    double best = -1.0;
    for (const Eigen::Vector2d& pixel : pixels) {
      const Eigen::Vector3d d = model.Unproject(pixel).direction;
      best = std::max(best, out.a.dot((d - normal.dot(d) * normal).normalized()));
    }
    return best;
  };
  const double cos_h = max_cosine(horizontal, down);
  const double cos_v = max_cosine(vertical, right);
  if (!(cos_h > 1e-6 && cos_v > 1e-6)) {
    throw Error(
        "LinearizeToCahv: the field of view reaches 90 degrees off the axis; a CAHV "
        "model cannot hold it");
  }
  const double tan_h = std::sqrt(1.0 - cos_h * cos_h) / cos_h;
  const double tan_v = std::sqrt(1.0 - cos_v * cos_v) / cos_v;
  const double hc = (output_size.x() - 1.0) / 2.0, vc = (output_size.y() - 1.0) / 2.0;
  const double hs = hc / tan_h, vs = vc / tan_v;
  out.h = hs * right + hc * out.a;
  out.v = vs * down + vc * out.a;
  out.o = out.a;
  out.r.setZero();
  return out;
}

}  // namespace areomap
