#include "areomap/map/dtm_gridding.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "test_support.h"

namespace areomap {
namespace {

GridPoint Point(double x, double y, double z, double sigma_z = 0.0) {
  GridPoint p;
  p.xyz = {x, y, z};
  p.covariance(2, 2) = sigma_z * sigma_z;
  return p;
}

GridSpec Grid(double x_left, double y_top, double posting, int width, int height) {
  GridSpec g;
  g.x_left = x_left;
  g.y_top = y_top;
  g.posting = posting;
  g.width = width;
  g.height = height;
  return g;
}

TEST(GridSpec, CoveringSnapsToThePosting) {
  const GridSpec g = GridSpec::Covering({-0.25, 1.05}, {0.93, 2.0}, 0.5);
  EXPECT_DOUBLE_EQ(g.x_left, -0.5);
  EXPECT_DOUBLE_EQ(g.y_top, 2.5);
  EXPECT_EQ(g.width, 3);   // [-0.5, 1.0)
  EXPECT_EQ(g.height, 3);  // (1.0, 2.5]
  EXPECT_TRUE(g.CellCenter(0, 0).isApprox(Eigen::Vector2d(-0.25, 2.25)));
}

// Random points on a plane: the TIN reproduces the plane inside their hull and nowhere else.
TEST(GridPoints, TinReproducesAPlaneInsideTheHull) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0.0, 10.0);
  std::vector<GridPoint> points;
  for (int i = 0; i < 2000; ++i) {
    const double x = u(rng), y = u(rng);
    points.push_back(Point(x, y, 3.0 + 0.2 * x - 0.1 * y));
  }
  GriddingOptions options;
  options.max_edge_m = 5.0;
  const GriddedLayers out = GridPoints(points, Grid(-2.0, 12.0, 0.25, 56, 56), options);
  int known = 0;
  for (int row = 0; row < 56; ++row) {
    for (int col = 0; col < 56; ++col) {
      const Eigen::Vector2d c = out.grid.CellCenter(col, row);
      const float z = out.elevation.at<float>(row, col);
      const bool outside = c.minCoeff() < 0.0 || c.maxCoeff() > 10.0;
      if (outside) {
        EXPECT_TRUE(std::isnan(z)) << c.transpose();
        continue;
      }
      if (std::isnan(z)) continue;  // Near the hull's boundary.
      ++known;
      EXPECT_NEAR(z, 3.0 + 0.2 * c.x() - 0.1 * c.y(), 1e-5);
    }
  }
  EXPECT_GT(known, 0.97 * 40 * 40);
  EXPECT_EQ(known, out.known_cells);
}

// A 3 m gap in the points is not bridged by triangles longer than 1 m.
TEST(GridPoints, TinLeavesGapsWiderThanTheEdgeLimit) {
  std::vector<GridPoint> points;
  for (double x = 0.0; x <= 10.0; x += 0.2) {
    for (double y = 0.0; y <= 4.0; y += 0.2) {
      if (x > 4.0 && x < 7.0) continue;
      points.push_back(Point(x, y, 1.0));
    }
  }
  GriddingOptions options;
  options.max_edge_m = 1.0;
  const GriddedLayers out = GridPoints(points, Grid(0.0, 4.0, 0.5, 20, 8), options);
  for (int row = 0; row < 8; ++row) {
    EXPECT_FLOAT_EQ(out.elevation.at<float>(row, 2), 1.0f);     // x = 1.25
    EXPECT_TRUE(std::isnan(out.elevation.at<float>(row, 11)));  // x = 5.75, in the gap.
  }
  options.max_edge_m = 5.0;
  const GriddedLayers bridged = GridPoints(points, Grid(0.0, 4.0, 0.5, 20, 8), options);
  EXPECT_FLOAT_EQ(bridged.elevation.at<float>(3, 11), 1.0f);
}

// Propagation: a TIN vertex keeps its own sigma; the centroid of a flat triangle of equal sigmas
// has sigma / sqrt(3).
TEST(GridPoints, TinSigmaFollowsTheBarycentricWeights) {
  const double s = 0.3;
  // Cell centres at (0.5, 0.5) ... : put a triangle whose centroid is a cell centre.
  const std::vector<GridPoint> points = {Point(-2.5, -0.5, 0.0, s), Point(3.5, -0.5, 0.0, s),
                                         Point(0.5, 3.5, 0.0, s)};
  // Centroid (0.5, 0.8333): use a grid whose cell centre is there.
  GriddingOptions options;
  options.max_edge_m = 10.0;
  const GriddedLayers out =
      GridPoints(points, Grid(0.0, 0.8333333333333 + 0.5, 1.0, 1, 1), options);
  EXPECT_NEAR(out.sigma.at<float>(0, 0), s / std::sqrt(3.0), 1e-6);
  EXPECT_NEAR(out.elevation.at<float>(0, 0), 0.0, 1e-6);
}

// On a slope the horizontal error of a point becomes height error: on z = x an x error of
// 0.2 m weighs like a height error of 0.2 m; on flat ground it does not count.
TEST(GridPoints, TinSigmaCountsHorizontalErrorOnSlopes) {
  const auto lattice = [](double slope, double var_x, double var_z) {
    std::vector<GridPoint> points;
    for (double x = 0.05; x < 6.0; x += 0.3) {
      for (double y = 0.1; y < 6.0; y += 0.3) {
        GridPoint p = Point(x, y, slope * x);
        p.covariance(0, 0) = var_x;
        p.covariance(2, 2) = var_z;
        points.push_back(p);
      }
    }
    return points;
  };
  const GridSpec grid = Grid(0.0, 6.0, 0.1, 60, 60);
  const GriddedLayers horizontal = GridPoints(lattice(1.0, 0.04, 0.0), grid, GriddingOptions{});
  const GriddedLayers vertical = GridPoints(lattice(1.0, 0.0, 0.04), grid, GriddingOptions{});
  const GriddedLayers flat = GridPoints(lattice(0.0, 0.04, 0.0), grid, GriddingOptions{});
  for (int row = 10; row < 50; row += 7) {
    for (int col = 10; col < 50; col += 7) {
      const float v = vertical.sigma.at<float>(row, col);
      EXPECT_GT(v, 0.2 / std::sqrt(3.0) - 1e-6);  // At most the weights of the centroid.
      EXPECT_LE(v, 0.2 + 1e-6);
      EXPECT_NEAR(horizontal.sigma.at<float>(row, col), v, 1e-5);
      EXPECT_NEAR(flat.sigma.at<float>(row, col), 0.0, 1e-6);
    }
  }
}

TEST(GridPoints, BinnedModesCountMeanMaxAndStddev) {
  const std::vector<GridPoint> points = {Point(0.2, 0.8, 1.0, 0.1), Point(0.7, 0.3, 2.0, 0.1),
                                         Point(0.5, 0.5, 4.0, 0.2), Point(1.5, 0.5, 7.0, 0.1)};
  const GridSpec grid = Grid(0.0, 1.0, 1.0, 3, 1);
  GriddingOptions options;
  options.method = GriddingMethod::kMean;
  const GriddedLayers mean = GridPoints(points, grid, options);
  EXPECT_EQ(mean.count.at<int32_t>(0, 0), 3);
  EXPECT_EQ(mean.count.at<int32_t>(0, 1), 1);
  EXPECT_EQ(mean.count.at<int32_t>(0, 2), 0);
  EXPECT_FLOAT_EQ(mean.elevation.at<float>(0, 0), 7.0f / 3.0f);
  EXPECT_NEAR(mean.stddev.at<float>(0, 0), std::sqrt(7.0 / 3.0), 1e-6);  // var of 1, 2, 4
  EXPECT_NEAR(mean.sigma.at<float>(0, 0), std::sqrt(0.01 + 0.01 + 0.04) / 3.0, 1e-7);
  EXPECT_TRUE(std::isnan(mean.stddev.at<float>(0, 1)));
  EXPECT_TRUE(std::isnan(mean.elevation.at<float>(0, 2)));
  EXPECT_EQ(mean.known_cells, 2);
  options.method = GriddingMethod::kMax;
  const GriddedLayers max = GridPoints(points, grid, options);
  EXPECT_FLOAT_EQ(max.elevation.at<float>(0, 0), 4.0f);
  EXPECT_NEAR(max.sigma.at<float>(0, 0), 0.2, 1e-7);
}

TEST(GridPoints, InverseDistanceWeightsByDistance) {
  // Cell centre (0.5, 0.5): points at distance 0.1 and 0.3 -> weights 100 and 11.1.
  const std::vector<GridPoint> points = {Point(0.6, 0.5, 1.0), Point(0.2, 0.5, 2.0),
                                         Point(1.5, 0.5, 9.0)};
  GriddingOptions options;
  options.method = GriddingMethod::kInverseDistance;
  options.idw_radius_m = 0.5;
  const GriddedLayers out = GridPoints(points, Grid(0.0, 1.0, 1.0, 3, 1), options);
  const double w1 = 1.0 / 0.01, w2 = 1.0 / 0.09;
  EXPECT_NEAR(out.elevation.at<float>(0, 0), (w1 * 1.0 + w2 * 2.0) / (w1 + w2), 1e-6);
  EXPECT_FLOAT_EQ(out.elevation.at<float>(0, 1), 9.0f);  // Its only point is 0 m away.
  EXPECT_TRUE(std::isnan(out.elevation.at<float>(0, 2)));
  options.idw_max_points = 1;  // Only the nearest.
  EXPECT_FLOAT_EQ(GridPoints(points, Grid(0.0, 1.0, 1.0, 3, 1), options).elevation.at<float>(0, 0),
                  1.0f);
}

TEST(GridPoints, RejectsBadInput) {
  std::vector<GridPoint> points = {Point(0.2, 0.8, 1.0), Point(0.2, 0.8, NAN)};
  EXPECT_NE(testing::ErrorMessageOf([&] {
              GridPoints(points, Grid(0.0, 1.0, 1.0, 1, 1), GriddingOptions{});
            }).find("point 1 is not finite"),
            std::string::npos);
  GriddingOptions bad;
  bad.max_edge_m = 0.0;
  EXPECT_NE(testing::ErrorMessageOf([&] { bad.Check(); }).find("GriddingOptions.max_edge_m"),
            std::string::npos);
  EXPECT_NE(testing::ErrorMessageOf([&] {
              GridPoints({}, Grid(0.0, 1.0, 1.0, 0, 1), GriddingOptions{});
            }).find("GridSpec.width"),
            std::string::npos);
  EXPECT_NE(testing::ErrorMessageOf([] {
              GriddingMethodFromString("kriging");
            }).find("expected tin, mean, max or idw"),
            std::string::npos);
}

}  // namespace
}  // namespace areomap
