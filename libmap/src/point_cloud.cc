#include "areomap/map/point_cloud.h"

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

}  // namespace areomap
