// KeepMostPreciseSource: where two stereo pairs of unlike precision see the same ground.
#include "areomap/map/point_cloud.h"

#include <gtest/gtest.h>

#include "areomap/map/error.h"

namespace areomap {
namespace {

// `count` points of pair `image_id` spread over the 0.25 m cell whose corner is (x0, y0), each
// with an isotropic 1 sigma of `sigma` per axis.
void AddPatch(PointCloud& cloud, uint16_t image_id, double x0, double y0, int count, double sigma) {
  for (int i = 0; i < count; ++i) {
    StereoPoint p;
    p.position = {x0 + 0.01 + 0.23 * (i % 5) / 4.0, y0 + 0.01 + 0.23 * (i / 5 % 5) / 4.0, 0.0};
    p.covariance = Eigen::Matrix3d::Identity() * sigma * sigma;
    p.image_id = image_id;
    cloud.points.push_back(p);
  }
}

int CountFrom(const PointCloud& cloud, uint16_t image_id) {
  int n = 0;
  for (const StereoPoint& p : cloud.points) n += p.image_id == image_id;
  return n;
}

TEST(KeepMostPreciseSource, DropsTheCoarsePairOnlyWhereThePrecisePairSeesTheGround) {
  // Pair 0 (Navcam-like, 0.4 m) covers cells A and B; pair 1 (Pancam-like, 0.1 m) covers B only.
  PointCloud cloud;
  AddPatch(cloud, 0, 10.0, 0.0, 20, 0.4);  // Cell A.
  AddPatch(cloud, 0, 10.5, 0.0, 20, 0.4);  // Cell B.
  AddPatch(cloud, 1, 10.5, 0.0, 20, 0.1);  // Cell B.
  const PointCloud kept = KeepMostPreciseSource(cloud, {});
  EXPECT_EQ(CountFrom(kept, 0), 20);  // Cell A keeps its only pair.
  EXPECT_EQ(CountFrom(kept, 1), 20);
  for (const StereoPoint& p : kept.points) {
    if (p.image_id == 0) {
      EXPECT_LT(p.position.x(), 10.25);  // Not a single coarse point in B.
    }
  }
  // Order is preserved.
  EXPECT_EQ(kept.points.front().position, cloud.points.front().position);
}

TEST(KeepMostPreciseSource, KeepsPairsOfLikePrecisionAndSparsePreciseOnes) {
  PointCloud cloud;
  AddPatch(cloud, 0, 0.0, 0.0, 20, 0.30);
  AddPatch(cloud, 1, 0.0, 0.0, 20, 0.55);  // Within the ratio of 2: both kept.
  AddPatch(cloud, 2, 0.0, 0.0, 3, 0.05);   // Too few to set the bar, precise: kept.
  AddPatch(cloud, 3, 0.0, 0.0, 3, 0.90);   // Sparse and coarser than 2 x 0.30: dropped.
  const PointCloud kept = KeepMostPreciseSource(cloud, {});
  EXPECT_EQ(CountFrom(kept, 0), 20);
  EXPECT_EQ(CountFrom(kept, 1), 20);
  EXPECT_EQ(CountFrom(kept, 2), 3);
  EXPECT_EQ(CountFrom(kept, 3), 0);
}

TEST(KeepMostPreciseSource, RejectsBadOptions) {
  PointCloud cloud;
  AddPatch(cloud, 0, 0.0, 0.0, 5, 0.1);
  PreciseSourceOptions options;
  options.sigma_ratio = 0.5;
  EXPECT_THROW(KeepMostPreciseSource(cloud, options), Error);
  options = {};
  options.cell_m = 0.0;
  EXPECT_THROW(KeepMostPreciseSource(cloud, options), Error);
  options = {};
  options.min_points = 0;
  EXPECT_THROW(KeepMostPreciseSource(cloud, options), Error);
  EXPECT_TRUE(KeepMostPreciseSource(PointCloud{}, {}).points.empty());
}

}  // namespace
}  // namespace areomap
