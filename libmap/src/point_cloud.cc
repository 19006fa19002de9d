#include "areomap/map/point_cloud.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <string>
#include <tuple>
#include <vector>

#include "areomap/map/error.h"

namespace areomap {
namespace {

// The cloud's frame, site and camera with the points for which keep(index, point) holds, in
// order (without copying the others first).
template <typename Keep>
PointCloud PointsWhere(const PointCloud& cloud, Keep keep) {
  PointCloud kept;
  kept.frame = cloud.frame;
  kept.site = cloud.site;
  kept.camera_center = cloud.camera_center;
  for (size_t i = 0; i < cloud.points.size(); ++i) {
    if (keep(i, cloud.points[i])) kept.points.push_back(cloud.points[i]);
  }
  return kept;
}

}  // namespace

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
  return PointsWhere(cloud, [&](size_t, const StereoPoint& p) {
    const double range = (p.position - cloud.camera_center).norm();
    const int step = std::clamp(
        static_cast<int>(std::lround(spacing_m * focal_px / std::max(range, 1e-3))), 1, max_step);
    const long col = std::lround(p.left_x), row = std::lround(p.left_y);
    return col % step == 0 && row % step == 0;
  });
}

void PreciseSourceOptions::Check() const {
  RequireOption(cell_m > 0.0, "PreciseSourceOptions.cell_m", "a positive cell size in metres");
  RequireOption(sigma_ratio >= 1.0, "PreciseSourceOptions.sigma_ratio", ">= 1");
  RequireOption(min_points >= 1, "PreciseSourceOptions.min_points", ">= 1");
}

PointCloud KeepMostPreciseSource(const PointCloud& cloud, const PreciseSourceOptions& options) {
  options.Check();
  using Key = std::tuple<int64_t, int64_t, uint16_t>;  // Cell column, cell row, source pair.
  const size_t n = cloud.points.size();
  std::vector<Key> keys(n);
  std::vector<double> sigma(n);
  for (size_t i = 0; i < n; ++i) {
    const StereoPoint& p = cloud.points[i];
    keys[i] = {static_cast<int64_t>(std::floor(p.position.x() / options.cell_m)),
               static_cast<int64_t>(std::floor(p.position.y() / options.cell_m)), p.image_id};
    sigma[i] = std::sqrt(std::max(p.covariance.trace(), 0.0));
  }
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t{0});
  // Grouped by cell, then pair; order within a group does not matter.
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return keys[a] < keys[b]; });

  // Sources in key order: [begin, end) of `order` and their median sigma.
  struct Source {
    size_t begin, end;
    double median;
  };
  std::vector<Source> sources;
  std::vector<double> scratch;
  for (size_t begin = 0; begin < n;) {
    size_t end = begin + 1;
    while (end < n && keys[order[end]] == keys[order[begin]]) ++end;
    scratch.clear();
    for (size_t k = begin; k < end; ++k) scratch.push_back(sigma[order[k]]);
    const auto middle = scratch.begin() + static_cast<long>(scratch.size() / 2);
    std::nth_element(scratch.begin(), middle, scratch.end());
    sources.push_back({begin, end, *middle});
    begin = end;
  }

  // Per cell: the smallest sigma of a source with at least min_points there sets the bar.
  std::vector<char> keep(n, 1);
  const auto cell_of = [&](const Source& source) {
    const Key& key = keys[order[source.begin]];
    return std::pair(std::get<0>(key), std::get<1>(key));
  };
  for (size_t first = 0; first < sources.size();) {
    size_t last = first + 1;
    while (last < sources.size() && cell_of(sources[last]) == cell_of(sources[first])) ++last;
    double best = std::numeric_limits<double>::infinity();
    for (size_t s = first; s < last; ++s) {
      const size_t count = sources[s].end - sources[s].begin;
      if (count >= static_cast<size_t>(options.min_points))
        best = std::min(best, sources[s].median);
    }
    for (size_t s = first; s < last; ++s) {
      if (!(sources[s].median > options.sigma_ratio * best)) continue;  // No bar: keep.
      for (size_t k = sources[s].begin; k < sources[s].end; ++k) keep[order[k]] = 0;
    }
    first = last;
  }

  return PointsWhere(cloud, [&](size_t i, const StereoPoint&) { return keep[i] != 0; });
}

}  // namespace areomap
