// Internal to rock extraction: a sparse 3D voxel index over a subset of a cloud's points, for
// the surface growth's nearest-neighbour and radius queries. The 2D PointGrid's cells (a fifth of
// the peak window, 10 cm) hold thousands of points where a rover camera sees the ground from a
// metre away; these voxels are a fraction of the largest query radius, so a query visits only
// the voxels its radius reaches. Units: metres of the points' frame.
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
  // Indexes `indices` (into `points`) in cubes of edge `voxel_m` (> 0).
  VoxelIndex(const std::vector<StereoPoint>& points, const std::vector<int>& indices,
             double voxel_m)
      : points_(points), voxel_(voxel_m) {
    std::vector<std::pair<uint64_t, int>> keyed;
    keyed.reserve(indices.size());
    for (int i : indices) keyed.emplace_back(Key(Voxel(points[i].position)), i);
    std::sort(keyed.begin(), keyed.end());
    order_.reserve(keyed.size());
    for (size_t k = 0; k < keyed.size(); ++k) {
      if (k == 0 || keyed[k].first != keyed[k - 1].first) {
        runs_[keyed[k].first] = {static_cast<int>(k), static_cast<int>(k)};
      }
      ++runs_[keyed[k].first].second;
      order_.push_back(keyed[k].second);
    }
  }

  // Distance from `p` to its nearest indexed point other than `self`, or `cap` when none is
  // nearer. Exact: voxel shells are visited until the next shell cannot hold a nearer point.
  double NearestDistance(const Eigen::Vector3d& p, int self, double cap) const {
    double best = cap;
    const Eigen::Vector3i c = Voxel(p);
    const int max_shell = static_cast<int>(std::ceil(cap / voxel_));
    for (int shell = 0; shell <= max_shell; ++shell) {
      // Points in shell s + 1 or beyond are at least s voxels away from p.
      if (shell > 0 && best <= (shell - 1) * voxel_) break;
      ForEachInShell(c, shell, [&](int j) {
        if (j == self) return;
        best = std::min(best, (points_[j].position - p).norm());
      });
    }
    return best;
  }

  // Calls f(index) for every indexed point within `radius` of `p` (3D).
  template <typename F>
  void ForEachWithin(const Eigen::Vector3d& p, double radius, F&& f) const {
    const Eigen::Vector3i c = Voxel(p);
    const int reach = static_cast<int>(std::ceil(radius / voxel_));
    for (int shell = 0; shell <= reach; ++shell) {
      ForEachInShell(c, shell, [&](int j) {
        if ((points_[j].position - p).norm() <= radius) f(j);
      });
    }
  }

 private:
  Eigen::Vector3i Voxel(const Eigen::Vector3d& p) const {
    return (p / voxel_).array().floor().cast<int>();
  }
  static uint64_t Key(const Eigen::Vector3i& v) {
    constexpr uint64_t kMask = (1u << 21) - 1;  // 21 bits per axis, offset to stay positive.
    const auto axis = [](int x) { return (static_cast<uint64_t>(x + (1 << 20))) & kMask; };
    return axis(v.x()) | axis(v.y()) << 21 | axis(v.z()) << 42;
  }
  // Points of the voxels at Chebyshev distance exactly `shell` from voxel c.
  template <typename F>
  void ForEachInShell(const Eigen::Vector3i& c, int shell, F&& f) const {
    for (int dz = -shell; dz <= shell; ++dz) {
      for (int dy = -shell; dy <= shell; ++dy) {
        const bool face = std::abs(dz) == shell || std::abs(dy) == shell;
        for (int dx = -shell; dx <= shell; dx += (face || shell == 0) ? 1 : 2 * shell) {
          const auto it = runs_.find(Key(c + Eigen::Vector3i(dx, dy, dz)));
          if (it == runs_.end()) continue;
          for (int k = it->second.first; k < it->second.second; ++k) f(order_[k]);
        }
      }
    }
  }

  const std::vector<StereoPoint>& points_;
  double voxel_;
  std::unordered_map<uint64_t, std::pair<int, int>> runs_;  // Key -> [begin, end) in order_.
  std::vector<int> order_;
};

}  // namespace areomap::rock_internal
