#include "areomap/landmarks/localization_error.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "areomap/map/error.h"

namespace areomap {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

TEST(LocalizationError, PolarCovarianceIsEq42) {
  // Looking north (theta = 0): sigma_r along x, r sigma_theta along y.
  const Eigen::Matrix2d north = PolarPositionCovariance(10.0, 0.0, 0.3, 1e-3);
  EXPECT_NEAR(north(0, 0), 0.09, 1e-15);
  EXPECT_NEAR(north(1, 1), 1e-4, 1e-15);
  EXPECT_NEAR(north(0, 1), 0.0, 1e-15);
  // Rotating the look direction rotates the ellipse: R diag R^T.
  const double t = 0.7;
  Eigen::Matrix2d r;
  r << std::cos(t), -std::sin(t), std::sin(t), std::cos(t);
  const Eigen::Matrix2d rotated = PolarPositionCovariance(10.0, t, 0.3, 1e-3);
  EXPECT_TRUE(rotated.isApprox(r * north * r.transpose(), 1e-12));
}

// Adjacent frame rotated by 3 degrees, scaled by 1.01 and shifted (the true transform), its
// origin in the current frame, and five landmarks seen from both sites.
const double kAngle = 3.0 * kDeg, kScale = 1.01;
const Eigen::Vector4d kTruth =
    Eigen::Vector4d(kScale * std::cos(kAngle), kScale* std::sin(kAngle), 12.0, -1.5);
const Eigen::Vector2d kAdjacent(12.0, -1.5);

// Tie points with the eq. 4.2 covariances and noise drawn at `noise_scale` x those sigmas.
std::vector<PlanarTiePoint> NoisyTies(std::mt19937* rng, double noise_scale) {
  const LocalizationCamera camera;
  const std::vector<Eigen::Vector2d> landmarks = {{5, 4}, {6, -5}, {8, 1}, {3, -1}, {7, 6}};
  std::normal_distribution<double> gauss(0.0, noise_scale);
  Eigen::Matrix2d sr;
  sr << kTruth(0), -kTruth(1), kTruth(1), kTruth(0);
  std::vector<PlanarTiePoint> ties;
  for (const Eigen::Vector2d& p : landmarks) {
    PlanarTiePoint t;
    t.covariance_current = camera.Covariance(p, Eigen::Vector2d::Zero());
    // Exact adjacent-frame coordinates: invert current = s R adjacent + (c, d).
    const Eigen::Vector2d exact_adjacent = sr.inverse() * (p - kTruth.tail<2>());
    // Noise drawn in the current frame; the adjacent frame's covariance is rotated in.
    const Eigen::Vector2d n1(gauss(*rng), gauss(*rng)), n2(gauss(*rng), gauss(*rng));
    t.in_current = p + t.covariance_current.llt().matrixL() * n1;
    t.covariance_adjacent =
        sr.inverse() * camera.Covariance(p, kAdjacent) * sr.inverse().transpose();
    t.in_adjacent = exact_adjacent + t.covariance_adjacent.llt().matrixL() * n2;
    ties.push_back(t);
  }
  return ties;
}

TEST(LocalizationError, GaussHelmertRecoversTheTransformAndItsCovariance) {
  Eigen::Matrix2d sample_cov = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d predicted = Eigen::Matrix2d::Zero();
  constexpr int kRuns = 400;
  std::mt19937 rng(3);
  for (int run = 0; run < kRuns; ++run) {
    const std::optional<ConformalTransform2d> fit = FitConformalTransform(NoisyTies(&rng, 1.0));
    ASSERT_TRUE(fit.has_value());
    EXPECT_EQ(fit->redundancy, 6);
    const Eigen::Vector2d error = fit->Apply(Eigen::Vector2d::Zero()) - kTruth.tail<2>();
    sample_cov += error * error.transpose() / kRuns;
    predicted += fit->PointCovariance(Eigen::Vector2d::Zero()) / kRuns;
  }
  // The scatter of the adjusted adjacent-site position matches eq. 4.8 (400 runs: the trace's
  // standard error is ~7 %).
  EXPECT_NEAR(sample_cov.trace() / predicted.trace(), 1.0, 0.2);
}

TEST(LocalizationError, LeaveOneOutChi2IsCalibratedAndFindsAnOutlier) {
  // Without outliers, each tie point's chi-square against the fit of the other four is
  // chi-square with 2 dof: mean 2 (400 runs x 5 points: standard error ~0.05). Leaving out the
  // fit's own uncertainty (eq. 4.8) gives a larger mean; testing the residuals of the fit that
  // includes the point against the tie points' covariances a smaller one (6 / 5 = 1.2).
  std::mt19937 rng(7);
  double sum = 0.0;
  int count = 0, above = 0;
  for (int run = 0; run < 400; ++run) {
    for (const double chi2 : LeaveOneOutChi2(NoisyTies(&rng, 1.0))) {
      ASSERT_TRUE(std::isfinite(chi2));
      sum += chi2;
      ++count;
      above += chi2 > 13.8 ? 1 : 0;
    }
  }
  EXPECT_EQ(count, 2000);
  EXPECT_NEAR(sum / count, 2.0, 0.2);
  EXPECT_LE(above, 8);  // 99.9 % quantile: ~2 of 2000 expected
  // One tie point moved by 0.5 m (about 5 sigma of its discrepancy, which is mostly the other
  // four's fit extrapolated to it): its chi-square is the largest and above 13.8 in 190 of 200
  // runs. (Each tie point's residual in the fit that includes the moved one, against the tie
  // point's own covariance, the test before LeaveOneOutChi2, singles it out in none of them: the
  // fit bends towards it and the largest residual falls on a correct tie point.)
  int found = 0;
  for (int run = 0; run < 200; ++run) {
    std::vector<PlanarTiePoint> ties = NoisyTies(&rng, 1.0);
    ties[2].in_current += 0.5 * Eigen::Vector2d::UnitY();
    const std::vector<double> chi2 = LeaveOneOutChi2(ties);
    const auto worst = std::max_element(chi2.begin(), chi2.end());
    found += worst - chi2.begin() == 2 && *worst > 13.8 ? 1 : 0;
  }
  EXPECT_GE(found, 170);
  // Two tie points: the other one alone cannot be fitted.
  const std::vector<PlanarTiePoint> five = NoisyTies(&rng, 1.0);
  const std::vector<PlanarTiePoint> two(five.begin(), five.begin() + 2);
  for (const double chi2 : LeaveOneOutChi2(two)) EXPECT_TRUE(std::isnan(chi2));
}

TEST(LocalizationError, PooledVarianceFactorMeasuresHowPessimisticTheCovariancesAre) {
  // Errors drawn at the stated sigmas give sigma_0^2 ~ 1; at half of them ~ 0.25. 400 fits of
  // redundancy 6: the pooled estimate's relative standard error is sqrt(2 / 2400) ~ 3 %.
  for (const double noise_scale : {1.0, 0.5}) {
    std::mt19937 rng(11);
    std::vector<SitePairError> fits;
    for (int run = 0; run < 400; ++run) {
      const std::optional<SitePairError> e =
          EvaluateSitePair(NoisyTies(&rng, noise_scale), kAdjacent);
      ASSERT_TRUE(e.has_value());
      EXPECT_EQ(e->redundancy, 6);
      fits.push_back(*e);
    }
    fits.push_back(SitePairError{});  // Redundancy 0 (two tie points): left out of the pool.
    const PooledVarianceFactor pooled = PoolVarianceFactor(fits);
    const double expected = noise_scale * noise_scale;
    EXPECT_EQ(pooled.fits, 400);
    EXPECT_EQ(pooled.redundancy, 2400);
    EXPECT_NEAR(pooled.estimate, expected, 0.12 * expected) << noise_scale;
    // The one-sided 95 % bound lies ~1.645 standard errors (~5 %) above the estimate.
    EXPECT_GT(pooled.upper_95, 1.03 * pooled.estimate);
    EXPECT_LT(pooled.upper_95, 1.08 * pooled.estimate);
  }
  const PooledVarianceFactor none = PoolVarianceFactor({SitePairError{}});
  EXPECT_EQ(none.fits, 0);
  EXPECT_TRUE(std::isnan(none.estimate));
  EXPECT_TRUE(std::isnan(none.upper_95));
}

TEST(LocalizationError, FitConvergesWithATiePointFarOff) {
  // A tie point on the wrong rock metres away: errors in both sets make the Gauss-Helmert
  // iteration converge linearly (steps shrinking by a constant factor), and the fit must still
  // end, with the large chi-square the tests need to see.
  std::mt19937 rng(17);
  for (const double off_m : {1.0, 3.0, 6.0}) {
    std::vector<PlanarTiePoint> ties = NoisyTies(&rng, 1.0);
    ties[3].in_current += off_m * Eigen::Vector2d(0.6, 0.8);
    const std::optional<ConformalTransform2d> fit = FitConformalTransform(ties);
    ASSERT_TRUE(fit.has_value()) << off_m;
    EXPECT_GT(fit->chi2, 30.0) << off_m;
    EXPECT_TRUE(fit->covariance.allFinite()) << off_m;
    ties.erase(ties.begin() + 3);
    const std::optional<ConformalTransform2d> rest = FitConformalTransform(ties);
    ASSERT_TRUE(rest.has_value()) << off_m;
    EXPECT_LT(rest->chi2, 20.0) << off_m;  // chi-square with 4 dof
  }
}

TEST(LocalizationError, FitNeedsTwoDistinctPoints) {
  PlanarTiePoint t;
  t.in_current = {1, 2};
  t.in_adjacent = {0, 1};
  EXPECT_FALSE(FitConformalTransform({t}).has_value());
  EXPECT_FALSE(FitConformalTransform({t, t}).has_value());
}

TEST(LocalizationError, ConvergenceAngleAndDistanceRatio) {
  EXPECT_NEAR(ConvergenceAngle({0, 0}, {{1, 1}, {1, -1}}), 90.0 * kDeg, 1e-12);
  EXPECT_NEAR(ConvergenceAngle({0, 0}, {{1, 0}, {-1, 0.001}, {0, 1}}), 180.0 * kDeg, 1e-3);
  EXPECT_EQ(ConvergenceAngle({0, 0}, {{1, 0}}), 0.0);
  EXPECT_NEAR(DistanceRatio({3, 0, 0}, {0, 0, 0}, {12, 0, 0}), 1.0 / 3.0, 1e-12);
  EXPECT_NEAR(DistanceRatio({9, 0, 0}, {0, 0, 0}, {12, 0, 0}), 1.0 / 3.0, 1e-12);
}

// Figures 4.2-4.5: the y-axis ranges [%] of the plots of RE against convergence 20-160 degrees
// (Navcam, sigma_p = 0.5 px) for 4, 6 and 9 landmarks, read from the figures' axis labels.
struct FigureRange {
  double length_m;
  int landmarks;
  double min_percent, max_percent;
};
constexpr FigureRange kFigureRanges[] = {
    {7.5, 4, 0.40, 0.54}, {7.5, 6, 0.39, 0.46}, {7.5, 9, 0.30, 0.40}, {15, 4, 0.78, 0.96},
    {15, 6, 0.72, 0.90},  {15, 9, 0.58, 0.70},  {20, 4, 1.00, 1.35},  {20, 6, 0.95, 1.25},
    {20, 9, 0.76, 0.94},  {25, 4, 1.25, 1.65},  {25, 6, 1.25, 1.55},  {25, 9, 0.90, 1.15}};

TEST(LocalizationError, ConfigurationStudyFallsInFigures42To45) {
  const LocalizationCamera navcam;
  for (const FigureRange& f : kFigureRanges) {
    for (double angle = 20.0; angle <= 160.0; angle += 10.0) {
      SCOPED_TRACE(testing::Message()
                   << f.landmarks << " landmarks, " << f.length_m << " m, " << angle << " deg");
      const ConfigurationSample s = EvaluateConfiguration(f.landmarks, f.length_m, angle, navcam);
      // The axis labels are read to their last digit: 0.05 % (0.01 % at 7.5 m) of slack.
      const double slack = f.length_m < 10.0 ? 0.01 : 0.05;
      EXPECT_GE(s.relative_error_percent, f.min_percent - slack);
      EXPECT_LE(s.relative_error_percent, f.max_percent + slack);
    }
  }
}

TEST(LocalizationError, ThreeAndTwoLandmarksAtShortTraverse) {
  const LocalizationCamera navcam;
  // Fig. 4.2b: three landmarks at 7.5 m plot between 0.60 and 0.74 %. Our triangle stays in that
  // band up to 100 degrees and grows to 0.95 % at 160 degrees (the figure's exact triangle
  // placement is not given).
  for (double angle = 20.0; angle <= 100.0; angle += 10.0) {
    const double re = EvaluateConfiguration(3, 7.5, angle, navcam).relative_error_percent;
    EXPECT_GE(re, 0.60 - 0.01) << angle;
    EXPECT_LE(re, 0.74 + 0.01) << angle;
  }
  // Table 4.1 / ch. 4.1.2: two landmarks reach the 1 % limit at 71 degrees and 7.5 m.
  EXPECT_NEAR(EvaluateConfiguration(2, 7.5, 71.0, navcam).relative_error_percent, 1.0, 0.05);
  // "The relative localization error is proportional to the traverse length".
  const double re15 = EvaluateConfiguration(6, 15.0, 90.0, navcam).relative_error_percent;
  const double re25 = EvaluateConfiguration(6, 25.0, 90.0, navcam).relative_error_percent;
  EXPECT_GT(re25, re15 * 1.5);
}

TEST(LocalizationError, StudyLandmarksHaveTheRequestedConvergence) {
  for (int n : {2, 3, 4, 6, 9}) {
    const auto points = StudyLandmarks(n, 20.0, 75.0);
    ASSERT_EQ(points.size(), static_cast<size_t>(n));
    EXPECT_NEAR(ConvergenceAngle({0, 0}, points), 75.0 * kDeg, 1e-9);
    EXPECT_NEAR(ConvergenceAngle({20, 0}, points), 75.0 * kDeg, 1e-9);
  }
  EXPECT_THROW(StudyLandmarks(5, 20.0, 75.0), Error);
  ConfigurationStudyOptions bad;
  bad.max_convergence_deg = 190.0;
  EXPECT_THROW(RunConfigurationStudy(bad), Error);
  bad = {};
  bad.convergence_step_deg = 1e-9;
  EXPECT_THROW(RunConfigurationStudy(bad), Error);
}

}  // namespace
}  // namespace areomap
