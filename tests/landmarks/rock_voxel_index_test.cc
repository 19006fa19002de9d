// The rock extraction's voxel index (landmarks/src/rock_voxel_index.h) against brute force:
// nearest distances (capped) and radius queries, on a dense patch and on sparse points.
#include "rock_voxel_index.h"

#include <algorithm>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace areomap {
namespace {

std::vector<StereoPoint> RandomPoints(int n, double extent, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<StereoPoint> points(static_cast<size_t>(n));
  for (StereoPoint& p : points) p.position = Eigen::Vector3d(u(rng), u(rng), 0.2 * u(rng));
  return points;
}

TEST(RockVoxelIndex, NearestAndRadiusQueriesMatchBruteForce) {
  constexpr double kCap = 0.1;
  // Dense (~mm spacing, as a metre from the camera) and sparse (~5 cm, as 20 m away).
  for (const auto& [count, extent] : {std::pair{4000, 0.05}, std::pair{300, 0.4}}) {
    SCOPED_TRACE(::testing::Message() << count << " points in +-" << extent << " m");
    const std::vector<StereoPoint> points = RandomPoints(count, extent, 7);
    std::vector<int> indexed;  // Every other point, as the points above a rock's plane.
    for (int i = 0; i < count; i += 2) indexed.push_back(i);
    const rock_internal::VoxelIndex index(points, indexed, points[0].position, kCap / 8.0);
    for (int q = 0; q < count; q += 7) {
      const Eigen::Vector3d& p = points[static_cast<size_t>(q)].position;
      double nearest = kCap;
      std::vector<int> within;
      const double radius = (q % 2 == 0 ? 0.3 : 1.0) * kCap;
      for (int j : indexed) {
        const double d = (points[static_cast<size_t>(j)].position - p).norm();
        if (j != q) nearest = std::min(nearest, d);
        if (d <= radius) within.push_back(j);
      }
      EXPECT_EQ(index.NearestDistance(p, q, kCap), nearest) << q;
      std::vector<int> got;
      index.ForEachWithin(p, radius, [&](int j) { got.push_back(j); });
      std::sort(got.begin(), got.end());
      EXPECT_EQ(got, within) << q;
    }
  }
  // Nothing within the cap: the cap.
  std::vector<StereoPoint> apart(2);
  apart[1].position = Eigen::Vector3d(1.0, 0.0, 0.0);
  const rock_internal::VoxelIndex lonely(apart, {0, 1}, Eigen::Vector3d::Zero(), kCap / 8.0);
  EXPECT_EQ(lonely.NearestDistance(apart[0].position, 0, kCap), kCap);
}

// Points on voxel corners, a query radius exactly reaching them, and coordinates far from the
// origin (a site frame hundreds of kilometres off) or wild (clamped to the border voxels).
TEST(RockVoxelIndex, CornersFarCoordinatesAndWildPointsAreExact) {
  constexpr double kVoxel = 0.0125;
  for (const double offset : {0.0, -0.075, 3.0e5, -3.0e6}) {
    SCOPED_TRACE(::testing::Message() << "offset " << offset);
    std::vector<StereoPoint> points;
    for (int i = -8; i <= 8; ++i) {
      for (int k = -8; k <= 8; ++k) {
        StereoPoint p;
        p.position = Eigen::Vector3d(offset + i * kVoxel, offset + k * kVoxel, 0.0);
        points.push_back(p);
      }
    }
    StereoPoint wild;
    wild.position = Eigen::Vector3d(offset, offset, -1e12);
    points.push_back(wild);
    std::vector<int> all(points.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    const rock_internal::VoxelIndex index(points, all, Eigen::Vector3d(offset, offset, 0.0),
                                          kVoxel);
    const Eigen::Vector3d centre = points[8 * 17 + 8].position;  // The middle of the lattice.
    for (const int steps : {1, 3, 8}) {
      const double radius = (centre - points[8 * 17 + 8 + steps].position).norm();
      std::vector<int> expected, got;
      for (int j : all) {
        if ((points[static_cast<size_t>(j)].position - centre).norm() <= radius) {
          expected.push_back(j);
        }
      }
      index.ForEachWithin(centre, radius, [&](int j) { got.push_back(j); });
      std::sort(got.begin(), got.end());
      EXPECT_EQ(got, expected) << steps;
    }
    EXPECT_NEAR(index.NearestDistance(centre, 8 * 17 + 8, 0.1), kVoxel, 1e-9);
    EXPECT_EQ(index.NearestDistance(wild.position, static_cast<int>(points.size()) - 1, 0.1), 0.1);
  }
}

}  // namespace
}  // namespace areomap
