// Internal to rock extraction: a sparse 3D voxel index over a subset of a cloud's points, for
// the surface growth's nearest-neighbour and radius queries. The 2D PointGrid's cells (a fifth of
// the peak window, 10 cm) hold thousands of points where a rover camera sees the ground from a
// metre away; these voxels are a fraction of the largest query radius, so a query visits only
// the voxels its radius reaches. Units: metres of the points' frame.
//
// Queries are exact: a query visits every voxel that the axis-aligned box p +- r (widened by a
// relative 1e-12 against rounding) overlaps, and compares true distances. Voxel coordinates are
// taken relative to `origin` and clamped to +-2^20 voxels (13 km at 1.25 cm), so any finite
// point is safe (a wild point far away lands in a border voxel: clamping never brings two
// points' voxels further apart, so no neighbour is lost, and the distances stay exact).
// Coordinates must be finite (CheckPointCloud guarantees it). Callback order is unspecified.
// The index keeps a reference to `points`, which must outlive it.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "areomap/map/point_cloud.h"

namespace areomap::rock_internal {

class VoxelIndex {
 public:
  // Indexes `indices` (into `points`) in cubes of edge `voxel_m` (> 0) laid from `origin`.
  VoxelIndex(const std::vector<StereoPoint>& points, const std::vector<int>& indices,
             const Eigen::Vector3d& origin, double voxel_m)
      : points_(points), origin_(origin), voxel_(voxel_m) {
    std::vector<std::pair<uint64_t, int>> keyed;
    keyed.reserve(indices.size());
    for (int i : indices) keyed.emplace_back(Key(Voxel(points[i].position)), i);
    std::sort(keyed.begin(), keyed.end());
    order_.reserve(keyed.size());
    runs_.reserve(keyed.size());
    for (size_t k = 0; k < keyed.size(); ++k) {
      const int at = static_cast<int>(k);
      if (k == 0 || keyed[k].first != keyed[k - 1].first) {
        runs_.emplace(keyed[k].first, std::pair<int, int>{at, at + 1});
      } else {
        runs_.find(keyed[k].first)->second.second = at + 1;
      }
      order_.push_back(keyed[k].second);
    }
  }
  VoxelIndex(std::vector<StereoPoint>&&, const std::vector<int>&, const Eigen::Vector3d&,
             double) = delete;  // The index refers to the points.

  // Distance from `p` to its nearest indexed point other than index `self` (which need not be
  // indexed), or `cap` (> 0) when none is nearer.
  double NearestDistance(const Eigen::Vector3d& p, int self, double cap) const {
    double best = cap;
    // Boxes of growing half-width; a box of half-width r holds every point within r of p.
    for (double r = std::min(voxel_, cap);; r = std::min(2.0 * r, cap)) {
      ForEachInBox(p, r, [&](int j) {
        if (j != self) best = std::min(best, (points_[j].position - p).norm());
      });
      if (best <= r || r >= cap) return best;
    }
  }

  // Calls f(index) for every indexed point within `radius` of `p` (3D, inclusive).
  template <typename F>
  void ForEachWithin(const Eigen::Vector3d& p, double radius, F&& f) const {
    ForEachInBox(p, radius, [&](int j) {
      if ((points_[j].position - p).norm() <= radius) f(j);
    });
  }

 private:
  static constexpr double kVoxelLimit = 1 << 20;  // Voxel coordinates in [-2^20, 2^20 - 1].

  // Voxel of a point, relative to the origin and clamped (in double, before the cast).
  Eigen::Vector3i Voxel(const Eigen::Vector3d& p) const {
    const Eigen::Array3d v = ((p - origin_) / voxel_).array().floor();
    return v.max(-kVoxelLimit).min(kVoxelLimit - 1.0).cast<int>();
  }
  static uint64_t Key(const Eigen::Vector3i& v) {
    // 21 bits per axis: the clamped range, offset to be non-negative, never aliases.
    const auto axis = [](int x) { return static_cast<uint64_t>(x + (1 << 20)); };
    return axis(v.x()) | axis(v.y()) << 21 | axis(v.z()) << 42;
  }
  // Points of every voxel that the box p +- half overlaps, widened by far more than the rounding
  // of p -+ half (half an ulp of the larger coordinate): a point within `half` of p has a voxel
  // between the corners' voxels, every step of Voxel() being monotone.
  template <typename F>
  void ForEachInBox(const Eigen::Vector3d& p, double half, F&& f) const {
    const double reach = half + 1e-12 * (half + voxel_ + p.cwiseAbs().maxCoeff());
    const Eigen::Vector3i lo = Voxel(p - Eigen::Vector3d::Constant(reach));
    const Eigen::Vector3i hi = Voxel(p + Eigen::Vector3d::Constant(reach));
    for (int z = lo.z(); z <= hi.z(); ++z) {
      for (int y = lo.y(); y <= hi.y(); ++y) {
        for (int x = lo.x(); x <= hi.x(); ++x) {
          const auto it = runs_.find(Key(Eigen::Vector3i(x, y, z)));
          if (it == runs_.end()) continue;
          for (int k = it->second.first; k < it->second.second; ++k) f(order_[k]);
        }
      }
    }
  }

  const std::vector<StereoPoint>& points_;
  Eigen::Vector3d origin_;
  double voxel_;
  std::unordered_map<uint64_t, std::pair<int, int>> runs_;  // Key -> [begin, end) in order_.
  std::vector<int> order_;
};

}  // namespace areomap::rock_internal
