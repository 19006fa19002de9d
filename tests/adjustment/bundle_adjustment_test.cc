#include "areomap/adjustment/bundle_adjustment.h"

#include <algorithm>
#include <cmath>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "areomap/adjustment/traverse_anchoring.h"
#include "areomap/map/error.h"
#include "bundle_simulation.h"

namespace areomap {
namespace {

using testing::SimulatedNetwork;
using testing::SimulatedNetworkOptions;
using testing::SimulateNetwork;

std::vector<Eigen::Vector3d> TruePositions(const SimulatedNetwork& net) {
  std::vector<Eigen::Vector3d> out;
  for (const Rigid3d& t : net.truth) out.push_back(t.translation);
  return out;
}

double MedianInitialRe(const AnchoredTraverse& anchored) {
  std::vector<double> re;
  for (const LegError& leg : anchored.legs) re.push_back(leg.initial_re);
  std::nth_element(re.begin(), re.begin() + re.size() / 2, re.end());
  return re[re.size() / 2];
}

// The generator's long traverse (46 sites, ~1.1 km) with 10 % odometry noise per leg (scale
// sigma 0.10, heading drift 2 deg per leg) and 8 stereo tie points per leg.
SimulatedNetworkOptions LongTraverseWithTenPercentOdometry() {
  SimulatedNetworkOptions options;
  options.telemetry.scale_sigma = 0.10;
  return options;
}

TEST(BundleAdjustment, RoverTiePointsBoundLongTraverseDriftToOnePercent) {
  const SimulatedNetwork net = SimulateNetwork(LongTraverseWithTenPercentOdometry());
  ASSERT_GT(net.length_m, 1000.0);
  const BundleResult result = AdjustBundle(net.input);
  const AnchoredTraverse anchored = AnchorTraverse(net.input, result, TruePositions(net));
  EXPECT_GT(MedianInitialRe(anchored), 0.05);  // The telemetry legs are off by ~10 %.
  EXPECT_LE(anchored.adjusted_end_error_m, 0.01 * net.length_m);
  EXPECT_LE(anchored.median_adjusted_re, 0.01);
  // Honest weights: sigma0 ~ 1 (redundancy > 1000, so within a few percent).
  EXPECT_GT(result.redundancy, 1000);
  EXPECT_NEAR(result.sigma0, 1.0, 0.1);
  // No outliers were simulated: alpha = 0.001 over 405 groups expects 0.4 false rejections.
  EXPECT_LE(result.rejected, 3);
  EXPECT_TRUE(result.sites[0].held);
  for (const SiteReport& s : result.sites) EXPECT_FALSE(s.only_priors) << s.site;
  std::printf(
      "length %.1f m: end-point error telemetry %.2f m, adjusted %.2f m; median leg RE "
      "telemetry %.2f %%, adjusted %.3f %%; sigma0 %.3f; %.3f s\n",
      net.length_m, anchored.initial_end_error_m, anchored.adjusted_end_error_m,
      100 * MedianInitialRe(anchored), 100 * anchored.median_adjusted_re, result.sigma0,
      result.solve_seconds);
}

// The same traverse with the tie points as Navcam pixels (0.5 px) through the CAHVOR models
// instead of their stereo points: the rigorous image model meets the same bounds.
TEST(BundleAdjustment, PixelObservationsThroughCahvorBoundTheDriftToo) {
  SimulatedNetworkOptions options = LongTraverseWithTenPercentOdometry();
  options.pixel_observations = true;
  const SimulatedNetwork net = SimulateNetwork(options);
  ASSERT_GT(net.input.image_observations.size(), 1000u);
  const BundleResult result = AdjustBundle(net.input);
  const AnchoredTraverse anchored = AnchorTraverse(net.input, result, TruePositions(net));
  EXPECT_LE(anchored.adjusted_end_error_m, 0.01 * net.length_m);
  EXPECT_LE(anchored.median_adjusted_re, 0.01);
  EXPECT_NEAR(result.sigma0, 1.0, 0.1);
  EXPECT_LE(result.rejected, 3);
  ASSERT_FALSE(result.images.empty());
  for (const ImageReport& image : result.images) EXPECT_LT(image.rms_px, 2.0) << image.image;
  std::printf(
      "pixels: %zu image observations in %zu images; end-point error %.2f m, median leg "
      "RE %.3f %%, sigma0 %.3f, %.3f s\n",
      net.input.image_observations.size(), result.images.size(), anchored.adjusted_end_error_m,
      100 * anchored.median_adjusted_re, result.sigma0, result.solve_seconds);
}

// Orbital control (0.25 m horizontal) at every site: absolute errors within 0.5 m and a reported
// 1 sigma that covers the true error about 68 % of the time (per horizontal axis).
TEST(BundleAdjustment, OrbitalControlGivesHonestSubHalfMetrePositions) {
  int covered = 0, tested = 0;
  double worst = 0.0;
  for (uint32_t seed : {1u, 2u}) {
    SimulatedNetworkOptions options = LongTraverseWithTenPercentOdometry();
    options.seed = seed;
    options.control_points_per_site = 2;
    const SimulatedNetwork net = SimulateNetwork(options);
    const BundleResult result = AdjustBundle(net.input);
    EXPECT_FALSE(result.sites[0].held);
    EXPECT_NEAR(result.sigma0, 1.0, 0.1);
    const AnchoredTraverse anchored = AnchorTraverse(net.input, result, TruePositions(net));
    for (const AnchoredSite& s : anchored.sites) {
      worst = std::max(worst, s.adjusted_error_m);
      EXPECT_LE(s.adjusted_error_m, 0.5) << "seed " << seed << " site " << s.site;
      for (int axis = 0; axis < 2; ++axis) {
        const double error = std::abs(s.position_in_traverse[axis] - s.truth_in_traverse[axis]);
        covered += error <= std::sqrt(s.covariance_in_traverse(axis, axis)) ? 1 : 0;
        ++tested;
      }
    }
  }
  const double coverage = static_cast<double>(covered) / tested;
  std::printf("worst horizontal error %.3f m; 1 sigma covers %.1f %% of %d axis errors\n", worst,
              100 * coverage, tested);
  EXPECT_GT(coverage, 0.50);
  EXPECT_LT(coverage, 0.85);
}

// Heights from an orbital DTM (0.3 m) at every site and no control: the vertical is anchored
// to the ellipsoid, the horizontal only by site 0's prior (50 m), and the covariance says so.
TEST(BundleAdjustment, DtmHeightsAnchorTheVertical) {
  SimulatedNetworkOptions options = LongTraverseWithTenPercentOdometry();
  options.traverse.site_count = 12;
  options.height_sigma_m = 0.3;
  const SimulatedNetwork net = SimulateNetwork(options);
  // Shift the whole network's initial heights by 5 m: only the heights can remove that.
  BundleInput input = net.input;
  for (Rigid3d& pose : input.initial_poses) pose.translation.z() += 5.0;
  const BundleResult result = AdjustBundle(input);
  EXPECT_FALSE(result.sites[0].held);
  EXPECT_NEAR(result.sigma0, 1.0, 0.25);
  for (size_t s = 0; s < result.sites.size(); ++s) {
    const double sigma_down = std::sqrt(result.sites[s].covariance(5, 5));
    EXPECT_LT(sigma_down, 0.3) << s;  // Better than one height: they are averaged.
    EXPECT_LT(std::abs(result.sites[s].adjusted.translation.z() - net.truth[s].translation.z()),
              4.0 * sigma_down)
        << s;
    EXPECT_GT(std::sqrt(result.sites[s].covariance(3, 3)), 10.0);  // Horizontal: site 0 prior.
    EXPECT_EQ(result.sites[s].heights, 1);
  }
}

TEST(BundleAdjustment, SiteWithoutLinksStaysOnItsPriorAndIsFlagged) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 8;
  options.sites_without_links = {7};
  const SimulatedNetwork net = SimulateNetwork(options);
  const BundleResult result = AdjustBundle(net.input);
  EXPECT_TRUE(result.sites[7].only_priors);
  for (int s = 0; s < 7; ++s) EXPECT_FALSE(result.sites[static_cast<size_t>(s)].only_priors);
  // Its pose relative to site 6 is the dead-reckoned one.
  const Rigid3d a_from_b = result.sites[6].adjusted.Inverse() * result.sites[7].adjusted;
  const RelativePosePrior& prior = net.input.priors.back();
  EXPECT_LT((a_from_b.translation - prior.a_from_b.translation).norm(), 1e-6);
  EXPECT_LT(a_from_b.rotation.angularDistance(prior.a_from_b.rotation), 1e-8);
  // And its uncertainty is site 6's plus the prior's.
  EXPECT_GT(result.sites[7].covariance(3, 3), result.sites[6].covariance(3, 3));
}

TEST(BundleAdjustment, ContradictoryControlPointIsRejectedWithReason) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 8;
  options.control_points_per_site = 2;
  SimulatedNetwork net = SimulateNetwork(options);
  ControlPoint& bad = net.input.control_points[7];  // Site 3's second control point.
  bad.position_mbf += Eigen::Vector3d(4.0, -3.0, 0.0);
  const BundleResult result = AdjustBundle(net.input);
  int rejected = 0;
  for (const ObservationReport& o : result.observations) {
    if (!o.rejected) continue;
    ++rejected;
    EXPECT_EQ(o.kind, ObservationKind::kControlPoint);
    EXPECT_EQ(o.id, bad.id);
    EXPECT_NE(o.reason.find("normalized residual test"), std::string::npos) << o.reason;
  }
  EXPECT_EQ(rejected, 1);
  const AnchoredTraverse anchored = AnchorTraverse(net.input, result, TruePositions(net));
  EXPECT_LE(anchored.sites[3].adjusted_error_m, 0.5);
}

TEST(BundleAdjustment, MismatchedTiePointIsRejected) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 6;
  SimulatedNetwork net = SimulateNetwork(options);
  net.input.tie_points[5].position_in_b += Eigen::Vector3d(2.0, 1.5, 0.0);  // A wrong match.
  const BundleResult result = AdjustBundle(net.input);
  ASSERT_EQ(result.rejected, 1);
  for (const ObservationReport& o : result.observations) {
    if (o.rejected) {
      EXPECT_EQ(o.id, net.input.tie_points[5].id);
    }
  }
}

// The Schur-complement covariance equals Ceres' own estimate (ceres::Covariance, sparse QR).
TEST(BundleAdjustment, SchurCovarianceMatchesCeresCovariance) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 6;
  options.control_points_per_site = 1;
  const SimulatedNetwork net = SimulateNetwork(options);
  const BundleResult schur = AdjustBundle(net.input);
  BundleOptions ceres_options;
  ceres_options.ceres_covariance = true;
  const BundleResult reference = AdjustBundle(net.input, ceres_options);
  ASSERT_EQ(schur.pose_covariance.rows(), 36);
  const double scale = reference.pose_covariance.norm();
  EXPECT_LT((schur.pose_covariance - reference.pose_covariance).norm(), 1e-6 * scale);
  for (const SiteReport& s : schur.sites) {
    EXPECT_GT(s.covariance(3, 3), 0.0);
    EXPECT_LT(std::sqrt(s.covariance(3, 3)), 0.25);  // Better than one control point.
  }
}

TEST(BundleAdjustment, IncrementalWindowThenFullMatchesBatch) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 10;
  const SimulatedNetwork net = SimulateNetwork(options);
  IncrementalBundle incremental(net.input.body, net.input.origin);
  for (int s = 0; s < net.input.site_count; ++s) {
    const testing::SiteLinks links = testing::LinksOfSite(net.input, s);
    const Rigid3d initial =
        s == 0 ? net.telemetry[0]
               : incremental.input().initial_poses.back() * links.priors.front().a_from_b;
    incremental.AddSite(initial, links.priors, links.tie_points, links.control_points);
    const BundleResult step = incremental.AdjustWindow(3);
    EXPECT_EQ(static_cast<int>(step.sites.size()), s + 1);
    if (s >= 3) {
      EXPECT_TRUE(step.sites[static_cast<size_t>(s - 3)].held);
    }
  }
  const BundleResult full = incremental.Full();
  const BundleResult batch = AdjustBundle(net.input);
  for (size_t s = 0; s < batch.sites.size(); ++s) {
    EXPECT_LT((full.sites[s].adjusted.translation - batch.sites[s].adjusted.translation).norm(),
              1e-4);
    EXPECT_LT((full.sites[s].covariance - batch.sites[s].covariance).norm(), 1e-6);
  }
}

TEST(BundleAdjustment, BadInputNamesTheObservation) {
  SimulatedNetworkOptions options;
  options.traverse.site_count = 3;
  SimulatedNetwork net = SimulateNetwork(options);
  net.input.tie_points[0].site_b = 9;
  EXPECT_THROW(
      {
        try {
          AdjustBundle(net.input);
        } catch (const Error& e) {
          EXPECT_NE(std::string(e.what()).find("tie point 't0-1-0' site_b: site 9"),
                    std::string::npos)
              << e.what();
          throw;
        }
      },
      Error);
  net = SimulateNetwork(options);
  net.input.tie_points[1].covariance_in_a = -Eigen::Matrix3d::Identity();
  try {
    AdjustBundle(net.input);
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not symmetric positive definite"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace areomap
