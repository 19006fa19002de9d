#include "areomap/map/point_cloud.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "areomap/map/error.h"

namespace areomap {

void CheckPointCloud(const PointCloud& cloud, const std::string& source, bool allow_empty) {
  if (cloud.points.empty() && !allow_empty) {
    throw Error(source + ": the point cloud is empty; expected at least one 3D point");
  }
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    const StereoPoint& p = cloud.points[i];
    if (!p.position.allFinite() || !p.covariance.allFinite()) {
      throw Error(source + ": point " + std::to_string(i) +
                  " has a non-finite position or covariance (NaN or Inf); expected finite metres");
    }
  }
}

PointCloud ThinToGroundSpacing(const PointCloud& cloud, double spacing_m, double focal_px,
                               int max_step) {
  RequireOption(spacing_m > 0.0, "ThinToGroundSpacing.spacing_m", "a positive spacing in metres");
  RequireOption(focal_px > 0.0, "ThinToGroundSpacing.focal_px", "a positive focal length [px]");
  RequireOption(max_step >= 1, "ThinToGroundSpacing.max_step", "at least 1");
  PointCloud thinned = cloud;
  thinned.points.clear();
  for (const StereoPoint& p : cloud.points) {
    const double range = (p.position - cloud.camera_center).norm();
    const int step = std::clamp(
        static_cast<int>(std::lround(spacing_m * focal_px / std::max(range, 1e-3))), 1, max_step);
    const long col = std::lround(p.left_x), row = std::lround(p.left_y);
    if (col % step == 0 && row % step == 0) thinned.points.push_back(p);
  }
  return thinned;
}

}  // namespace areomap
