#include "areomap/map/camera_footprint.h"

#include <cmath>

#include "areomap/map/error.h"

namespace areomap {

std::vector<Eigen::Vector2d> GroundFootprint(const CameraModel& model,
                                             const Eigen::Vector2i& image_size, double ground_z,
                                             double max_range_m, int samples_per_edge) {
  RequireOption(image_size.minCoeff() > 0, "GroundFootprint image_size", "positive");
  RequireOption(max_range_m > 0.0, "GroundFootprint max_range_m", "a positive range [m]");
  RequireOption(samples_per_edge >= 1, "GroundFootprint samples_per_edge", ">= 1");
  const double w = image_size.x() - 1.0, h = image_size.y() - 1.0;
  const std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> edges = {
      {{0, 0}, {w, 0}}, {{w, 0}, {w, h}}, {{w, h}, {0, h}}, {{0, h}, {0, 0}}};
  std::vector<Eigen::Vector2d> polygon;
  for (const auto& [from, to] : edges) {
    for (int i = 0; i < samples_per_edge; ++i) {
      const Eigen::Vector2d pixel =
          from + (to - from) * (static_cast<double>(i) / samples_per_edge);
      const CameraRay ray = model.Unproject(pixel);
      const Eigen::Vector2d horizontal = ray.direction.head<2>();
      const double depth = ground_z - ray.origin.z();
      Eigen::Vector2d point;
      bool hit = false;
      if (ray.direction.z() > 1e-9 && depth > 0.0) {
        const Eigen::Vector3d ground = ray.origin + (depth / ray.direction.z()) * ray.direction;
        if ((ground - ray.origin).head<2>().norm() <= max_range_m) {
          point = ground.head<2>();
          hit = true;
        }
      }
      if (!hit) {
        const Eigen::Vector2d dir =
            horizontal.norm() > 1e-12 ? horizontal.normalized() : Eigen::Vector2d(1.0, 0.0);
        point = ray.origin.head<2>() + max_range_m * dir;
      }
      polygon.push_back(point);
    }
  }
  return polygon;
}

double PolygonArea(const std::vector<Eigen::Vector2d>& polygon) {
  double twice = 0.0;
  for (size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector2d& a = polygon[i];
    const Eigen::Vector2d& b = polygon[(i + 1) % polygon.size()];
    twice += a.x() * b.y() - b.x() * a.y();
  }
  return 0.5 * std::abs(twice);
}

}  // namespace areomap
