#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "areomap/crater/ellipse.h"
#include "areomap/crater/ellipse_fit.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

constexpr double kPi = std::numbers::pi;

// Smallest difference of two axis directions [rad], modulo pi.
double AxisAngleDifference(double a, double b) {
  const double d = std::abs(WrapAxisAngle(a) - WrapAxisAngle(b));
  return std::min(d, kPi - d);
}

// Compact text for RecordProperty: 6 significant digits.
std::string Num(double value) {
  std::ostringstream out;
  out << std::setprecision(6) << value;
  return out.str();
}

double ConicValue(const ConicCoefficients& k, const Eigen::Vector2d& p) {
  const double x = p.x();
  const double y = p.y();
  return k(0) * x * x + k(1) * x * y + k(2) * y * y + k(3) * x + k(4) * y + k(5);
}

// Points at evenly spaced eccentric anomalies in [t0, t1) with isotropic Gaussian noise.
std::vector<Eigen::Vector2d> SampleArc(const Ellipse& e, double t0, double t1, int n,
                                       double noise_sigma, std::mt19937* rng) {
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < n; ++i) {
    const double t = t0 + (t1 - t0) * i / n;
    Eigen::Vector2d p = e.PointAt(t);
    if (noise_sigma > 0.0) p += noise_sigma * Eigen::Vector2d(noise(*rng), noise(*rng));
    points.push_back(p);
  }
  return points;
}

// Unsigned distance to the curve by dense sampling plus golden-section polishing.
double BruteForceDistance(const Ellipse& e, const Eigen::Vector2d& p) {
  constexpr int kSamples = 1 << 16;
  const auto squared = [&](double t) { return (e.PointAt(t) - p).squaredNorm(); };
  const double h = 2.0 * kPi / kSamples;
  double best = std::numeric_limits<double>::infinity();
  double best_t = 0.0;
  for (int i = 0; i < kSamples; ++i) {
    const double d = squared(i * h);
    if (d < best) {
      best = d;
      best_t = i * h;
    }
  }
  double lo = best_t - h;
  double hi = best_t + h;
  const double ratio = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int i = 0; i < 100; ++i) {
    const double m1 = hi - ratio * (hi - lo);
    const double m2 = lo + ratio * (hi - lo);
    if (squared(m1) < squared(m2)) {
      hi = m2;
    } else {
      lo = m1;
    }
  }
  return std::sqrt(std::min(best, squared(0.5 * (lo + hi))));
}

std::vector<Ellipse> TestEllipses() {
  return {
      Ellipse{{12.5, -3.0}, 10.0, 4.0, 0.0},       Ellipse{{-40.0, 7.25}, 25.0, 24.0, 0.7},
      Ellipse{{312.4, -87.6}, 55.0, 31.0, 2.2},    Ellipse{{0.0, 0.0}, 8.0, 1.0, 0.5 * kPi},
      Ellipse{{1.0e5, -2.0e5}, 406.3, 382.5, 3.1},
  };
}

TEST(EllipseConic, RoundTripsRotatedEllipses) {
  for (const Ellipse& e : TestEllipses()) {
    const ConicCoefficients conic = e.ToConic();
    EXPECT_LT(ConicValue(conic, e.center), 0.0);
    for (double t = 0.0; t < 2.0 * kPi; t += 0.4) {
      EXPECT_NEAR(ConicValue(conic, e.PointAt(t)), 0.0, 1e-8);
    }
    for (const double scale : {1.0, -3.7, 1e-6}) {
      const std::optional<Ellipse> back = Ellipse::FromConic(scale * conic);
      ASSERT_TRUE(back.has_value()) << "scale " << scale;
      const double tolerance = 1e-9 * e.semi_major;
      EXPECT_LT((back->center - e.center).norm(), tolerance * 1e3)  // centre far from origin
          << "scale " << scale;
      EXPECT_NEAR(back->semi_major, e.semi_major, tolerance);
      EXPECT_NEAR(back->semi_minor, e.semi_minor, tolerance);
      EXPECT_LT(AxisAngleDifference(back->angle, e.angle), 1e-8);
      EXPECT_TRUE(back->IsValid());
    }
  }
}

TEST(EllipseConic, RejectsConicsThatAreNotRealEllipses) {
  ConicCoefficients hyperbola;  // x^2 - y^2 - 1 = 0
  hyperbola << 1.0, 0.0, -1.0, 0.0, 0.0, -1.0;
  EXPECT_FALSE(Ellipse::FromConic(hyperbola).has_value());
  ConicCoefficients rotated_hyperbola;  // xy - 1 = 0
  rotated_hyperbola << 0.0, 1.0, 0.0, 0.0, 0.0, -1.0;
  EXPECT_FALSE(Ellipse::FromConic(rotated_hyperbola).has_value());
  ConicCoefficients parabola;  // x^2 - y = 0
  parabola << 1.0, 0.0, 0.0, 0.0, -1.0, 0.0;
  EXPECT_FALSE(Ellipse::FromConic(parabola).has_value());
  ConicCoefficients imaginary;  // x^2 + y^2 + 1 = 0
  imaginary << 1.0, 0.0, 1.0, 0.0, 0.0, 1.0;
  EXPECT_FALSE(Ellipse::FromConic(imaginary).has_value());
  ConicCoefficients point;  // x^2 + y^2 = 0
  point << 1.0, 0.0, 1.0, 0.0, 0.0, 0.0;
  EXPECT_FALSE(Ellipse::FromConic(point).has_value());
  EXPECT_FALSE(Ellipse::FromConic(ConicCoefficients::Zero()).has_value());
}

TEST(EllipseGeometry, ReportsShapeFiguresOfVictoriaCrater) {
  // Dissertation ch. 2.2.1: a = 406.3 m, b = 382.5 m, eccentricity 0.34.
  const Ellipse victoria{{0.0, 0.0}, 406.3, 382.5, 0.0};
  EXPECT_NEAR(victoria.Eccentricity(), 0.34, 0.005);
  EXPECT_DOUBLE_EQ(victoria.MeanRadius(), 394.4);
  EXPECT_NEAR(victoria.Area(), kPi * 406.3 * 382.5, 1e-9);
  EXPECT_DOUBLE_EQ((Ellipse{{0.0, 0.0}, 3.0, 3.0, 0.0}.Eccentricity()), 0.0);
}

TEST(EllipseGeometry, NormalizedSwapsAxesAndWrapsAngle) {
  const Ellipse e{{1.0, 2.0}, 3.0, 5.0, -0.25};
  EXPECT_FALSE(e.IsValid());
  const Ellipse n = e.Normalized();
  EXPECT_TRUE(n.IsValid());
  EXPECT_DOUBLE_EQ(n.semi_major, 5.0);
  EXPECT_DOUBLE_EQ(n.semi_minor, 3.0);
  EXPECT_NEAR(n.angle, 0.5 * kPi - 0.25, 1e-15);
  // Same curve: a point of the original lies on the normalized ellipse.
  for (double t = 0.0; t < 2.0 * kPi; t += 0.5) {
    EXPECT_NEAR(n.SignedDistance(e.PointAt(t)), 0.0, 1e-12);
  }
  EXPECT_NEAR(WrapAxisAngle(-1e-18), 0.0, 1e-15);
  EXPECT_NEAR(WrapAxisAngle(7.0 * kPi + 0.1), 0.1, 1e-12);
}

TEST(EllipseDistance, MatchesBruteForceSamplingEverywhere) {
  std::mt19937 rng(20080101);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  double worst_relative = 0.0;
  for (const Ellipse& e : TestEllipses()) {
    const double a = e.semi_major;
    const double b = e.semi_minor;
    // Points in the ellipse frame: centre, axes inside and outside, near the curve, far.
    std::vector<Eigen::Vector2d> local = {{0.0, 0.0},     {0.3 * a, 0.0},   {-0.9 * a, 0.0},
                                          {1.5 * a, 0.0}, {-a, 0.0},        {0.0, 0.5 * b},
                                          {0.0, -b},      {0.0, 2.0 * b},   {0.0, -3.0 * b},
                                          {a, b},         {0.999 * a, 0.0}, {0.0, 1.001 * b}};
    for (int i = 0; i < 40; ++i) local.emplace_back(2.0 * a * unit(rng), 2.0 * b * unit(rng));
    for (int i = 0; i < 10; ++i) {
      const double t = kPi * unit(rng);
      const double r = 1.0 + 1e-3 * unit(rng);
      local.emplace_back(r * a * std::cos(t), r * b * std::sin(t));
    }
    const double c = std::cos(e.angle);
    const double s = std::sin(e.angle);
    for (const Eigen::Vector2d& q : local) {
      const Eigen::Vector2d p =
          e.center + Eigen::Vector2d(c * q.x() - s * q.y(), s * q.x() + c * q.y());
      const double d = e.SignedDistance(p);
      const double expected = BruteForceDistance(e, p);
      const double scale = std::max(expected, 1e-3 * b);
      EXPECT_NEAR(std::abs(d), expected, 1e-6 * scale)
          << "point in ellipse frame " << q.transpose();
      worst_relative = std::max(worst_relative, std::abs(std::abs(d) - expected) / scale);
      const double level = (q.x() / a) * (q.x() / a) + (q.y() / b) * (q.y() / b);
      if (level < 1.0 - 1e-9) {
        EXPECT_LT(d, 0.0) << q.transpose();
      }
      if (level > 1.0 + 1e-9) {
        EXPECT_GT(d, 0.0) << q.transpose();
      }
      // The closest point is on the curve at distance |d|.
      const Eigen::Vector2d x = e.ClosestPoint(p);
      EXPECT_NEAR(e.SignedDistance(x), 0.0, 1e-9 * a);
      EXPECT_NEAR((x - p).norm(), std::abs(d), 1e-9 * a);
      EXPECT_LT((e.PointAt(e.ClosestParameter(p)) - x).norm(), 1e-9 * a);
    }
  }
  RecordProperty("worst_relative_error", Num(worst_relative));
  EXPECT_LT(worst_relative, 1e-6);
}

TEST(EllipseDistance, CentreOfEllipseIsSemiMinorInside) {
  const Ellipse e{{5.0, -2.0}, 7.0, 3.0, 1.0};
  EXPECT_NEAR(e.SignedDistance(e.center), -3.0, 1e-12);
  const Ellipse circle{{0.0, 0.0}, 2.5, 2.5, 0.0};
  EXPECT_NEAR(circle.SignedDistance({0.0, 0.0}), -2.5, 1e-12);
  EXPECT_NEAR(circle.SignedDistance({3.0, 4.0}), 2.5, 1e-12);
  EXPECT_TRUE(std::isnan((Ellipse{{0.0, 0.0}, 1.0, 0.0, 0.0}.SignedDistance({1.0, 1.0}))));
}

TEST(EllipseDistance, GradientMatchesCentralDifferences) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const Ellipse e{{3.0, -1.0}, 20.0, 12.0, 0.8};
  for (int i = 0; i < 50; ++i) {
    const Eigen::Vector2d p = e.center + Eigen::Vector2d(40.0 * unit(rng), 40.0 * unit(rng));
    if ((p - e.center).norm() < 2.0) continue;  // gradient undefined at the centre
    const Eigen::Matrix<double, 5, 1> gradient = e.SignedDistanceGradient(p);
    constexpr double kStep = 1e-6;
    for (int k = 0; k < 5; ++k) {
      Ellipse plus = e;
      Ellipse minus = e;
      double* fields_plus[5] = {&plus.center.x(), &plus.center.y(), &plus.semi_major,
                                &plus.semi_minor, &plus.angle};
      double* fields_minus[5] = {&minus.center.x(), &minus.center.y(), &minus.semi_major,
                                 &minus.semi_minor, &minus.angle};
      *fields_plus[k] += kStep;
      *fields_minus[k] -= kStep;
      const double numeric = (plus.SignedDistance(p) - minus.SignedDistance(p)) / (2.0 * kStep);
      EXPECT_NEAR(gradient(k), numeric, 1e-6) << "parameter " << k << " point " << p.transpose();
    }
  }
}

TEST(FitEllipseDirect, RecoversRotatedEllipseFromNoiseFreeFullRim) {
  std::mt19937 rng(1);
  double worst = 0.0;
  for (const Ellipse& truth : TestEllipses()) {
    const std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.0, 2.0 * kPi, 100, 0.0, &rng);
    const std::optional<Ellipse> fit = FitEllipseDirect(points);
    ASSERT_TRUE(fit.has_value());
    // OpenCV works in float on centred, unit-scaled points: 1e-6 of the size.
    const double tolerance = 1e-6 * truth.semi_major;
    EXPECT_LT((fit->center - truth.center).norm(), tolerance);
    EXPECT_NEAR(fit->semi_major, truth.semi_major, tolerance);
    EXPECT_NEAR(fit->semi_minor, truth.semi_minor, tolerance);
    EXPECT_LT(AxisAngleDifference(fit->angle, truth.angle), 1e-5);
    worst = std::max(
        {worst, (fit->center - truth.center).norm() / truth.semi_major,
         std::abs(fit->semi_major / truth.semi_major - 1.0),
         std::abs(fit->semi_minor / truth.semi_major - truth.semi_minor / truth.semi_major)});
  }
  RecordProperty("worst_error_relative_to_semi_major", Num(worst));
}

TEST(FitEllipseDirect, RecoversRotatedEllipseFromNoisyHalfArc) {
  // 400 edge points (1.3 per px of arc) with 0.3 px noise; the centre's scatter across the
  // arc's open side is ~0.16 px (1 sigma), so 0.5 px is a 3-sigma bound.
  const Ellipse truth{{312.4, -87.6}, 60.0, 40.0, 2.2};
  double worst_center = 0.0;
  double worst_axis = 0.0;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    std::mt19937 rng(seed);
    const std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.3, 0.3 + kPi, 400, 0.3, &rng);
    const std::optional<Ellipse> fit = FitEllipseDirect(points);
    ASSERT_TRUE(fit.has_value());
    EXPECT_LT((fit->center - truth.center).norm(), 0.5) << "seed " << seed;
    EXPECT_NEAR(fit->semi_major / truth.semi_major, 1.0, 0.02) << "seed " << seed;
    EXPECT_NEAR(fit->semi_minor / truth.semi_minor, 1.0, 0.02) << "seed " << seed;
    worst_center = std::max(worst_center, (fit->center - truth.center).norm());
    worst_axis = std::max({worst_axis, std::abs(fit->semi_major / truth.semi_major - 1.0),
                           std::abs(fit->semi_minor / truth.semi_minor - 1.0)});
  }
  RecordProperty("worst_center_error_px", Num(worst_center));
  RecordProperty("worst_relative_axis_error", Num(worst_axis));
}

TEST(FitEllipseFast, RecoversFullRimToAThousandthAndNoisyHalfArcLikeTheDirectFit) {
  // Noise-free full rims: the header promises ~1e-3 of the size (one float AMS fit), with all
  // points and with more than kFastFitMaxPoints (AMS then sees an even subset).
  std::mt19937 rng(1);
  for (const int count : {100, 1000}) {
    for (const Ellipse& truth : TestEllipses()) {
      const std::vector<Eigen::Vector2d> points =
          SampleArc(truth, 0.0, 2.0 * kPi, count, 0.0, &rng);
      const std::optional<Ellipse> fit = FitEllipseFast(points);
      ASSERT_TRUE(fit.has_value());
      const double tolerance = 1e-3 * truth.semi_major;
      EXPECT_LT((fit->center - truth.center).norm(), tolerance) << count << " points";
      EXPECT_NEAR(fit->semi_major, truth.semi_major, tolerance) << count << " points";
      EXPECT_NEAR(fit->semi_minor, truth.semi_minor, tolerance) << count << " points";
    }
  }
  // A noisy half arc of 400 points (0.3 px noise). AMS sees every 4th: 100 points, whose
  // 3-sigma centre bound is 1.0 px (the direct-fit test's 0.5 px for 400 points, x sqrt(4)).
  const Ellipse truth{{312.4, -87.6}, 60.0, 40.0, 2.2};
  for (unsigned seed = 1; seed <= 10; ++seed) {
    std::mt19937 noise(seed);
    const std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.3, 0.3 + kPi, 400, 0.3, &noise);
    const std::optional<Ellipse> fit = FitEllipseFast(points);
    ASSERT_TRUE(fit.has_value());
    EXPECT_LT((fit->center - truth.center).norm(), 1.0) << "seed " << seed;
    EXPECT_NEAR(fit->semi_major / truth.semi_major, 1.0, 0.02) << "seed " << seed;
    EXPECT_NEAR(fit->semi_minor / truth.semi_minor, 1.0, 0.02) << "seed " << seed;
  }
  EXPECT_FALSE(FitEllipseFast({{0, 0}, {1, 0}, {0, 1}, {-1, 0}}).has_value());
}

TEST(FitEllipseDirect, RejectsTooFewOrCollinearPoints) {
  EXPECT_FALSE(FitEllipseDirect({}).has_value());
  EXPECT_FALSE(FitEllipseDirect({{0, 0}, {1, 0}, {0, 1}, {-1, 0}}).has_value());
  std::vector<Eigen::Vector2d> line;
  for (int i = 0; i < 20; ++i) line.emplace_back(i, 2.0 * i + 1.0);
  EXPECT_FALSE(FitEllipseDirect(line).has_value());
  // Four finite points plus a NaN are still too few.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(FitEllipseDirect({{0, 0}, {1, 0}, {0, 1}, {-1, 0}, {nan, 0}}).has_value());
}

TEST(RefineEllipseGeometric, RecoversExactEllipseFromNoiseFreeArc) {
  const Ellipse truth{{-40.0, 7.25}, 25.0, 18.0, 0.7};
  std::mt19937 rng(3);
  const std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.0, 0.6 * kPi, 60, 0.0, &rng);
  const Ellipse start{{-38.0, 8.0}, 23.0, 17.0, 0.9};
  const EllipseFitSummary summary = RefineEllipseGeometric(start, points);
  EXPECT_TRUE(summary.converged) << summary.BriefReport();
  EXPECT_EQ(summary.num_points, 60);
  EXPECT_LT((summary.ellipse.center - truth.center).norm(), 1e-6);
  EXPECT_NEAR(summary.ellipse.semi_major, truth.semi_major, 1e-6);
  EXPECT_NEAR(summary.ellipse.semi_minor, truth.semi_minor, 1e-6);
  EXPECT_LT(AxisAngleDifference(summary.ellipse.angle, truth.angle), 1e-7);
  EXPECT_LT(summary.rms_residual, 1e-8);
  EXPECT_GT(summary.initial_rms_residual, 0.1);
}

TEST(RefineEllipseGeometric, ImprovesOnDirectFitForNoisyPartialArc) {
  // Dense edges (2000 points) on half the rim of a small crater with 1 px noise: the
  // algebraic fit's bias (~noise^2 / radius) dominates its scatter; the geometric fit has
  // no such bias.
  const Ellipse truth{{500.0, 250.0}, 40.0, 30.0, 0.4};
  double direct_error = 0.0;
  double refined_error = 0.0;
  double direct_axis_error = 0.0;
  double refined_axis_error = 0.0;
  constexpr int kTrials = 20;
  GeometricFitOptions least_squares;
  least_squares.loss = RobustLoss::kNone;
  for (int trial = 0; trial < kTrials; ++trial) {
    std::mt19937 rng(1000 + trial);
    const std::vector<Eigen::Vector2d> points = SampleArc(truth, 1.0, 1.0 + kPi, 2000, 1.0, &rng);
    const std::optional<Ellipse> direct = FitEllipseDirect(points);
    ASSERT_TRUE(direct.has_value());
    const EllipseFitSummary refined = RefineEllipseGeometric(*direct, points);
    ASSERT_TRUE(refined.converged) << refined.BriefReport();
    // Plain least squares never ends with a larger RMS distance than it started from.
    const EllipseFitSummary plain = RefineEllipseGeometric(*direct, points, least_squares);
    EXPECT_LE(plain.rms_residual, plain.initial_rms_residual + 1e-12);
    direct_error += (direct->center - truth.center).norm() / kTrials;
    refined_error += (refined.ellipse.center - truth.center).norm() / kTrials;
    direct_axis_error += std::abs(direct->semi_major - truth.semi_major) / kTrials;
    refined_axis_error += std::abs(refined.ellipse.semi_major - truth.semi_major) / kTrials;
  }
  RecordProperty("direct_mean_center_error_px", Num(direct_error));
  RecordProperty("refined_mean_center_error_px", Num(refined_error));
  EXPECT_LT(refined_error, 0.7 * direct_error)
      << "direct " << direct_error << " px, refined " << refined_error << " px";
  EXPECT_LT(refined_axis_error, 0.7 * direct_axis_error)
      << "direct " << direct_axis_error << " px, refined " << refined_axis_error << " px";
}

TEST(RefineEllipseGeometric, ReportedSigmaMatchesEmpiricalScatter) {
  const Ellipse truth{{200.0, -120.0}, 50.0, 35.0, 1.1};
  constexpr int kTrials = 50;
  constexpr double kNoise = 0.5;  // px
  std::vector<double> dx;
  std::vector<double> dy;
  std::vector<double> da;
  double sigma_x = 0.0;
  double sigma_y = 0.0;
  double sigma_a = 0.0;
  double sigma0 = 0.0;
  for (int trial = 0; trial < kTrials; ++trial) {
    std::mt19937 rng(5000 + trial);
    const std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.0, 1.1 * kPi, 120, kNoise, &rng);
    const std::optional<Ellipse> direct = FitEllipseDirect(points);
    ASSERT_TRUE(direct.has_value());
    const EllipseFitSummary s = RefineEllipseGeometric(*direct, points);
    ASSERT_TRUE(s.converged) << s.BriefReport();
    ASSERT_TRUE(s.covariance_valid);
    dx.push_back(s.ellipse.center.x() - truth.center.x());
    dy.push_back(s.ellipse.center.y() - truth.center.y());
    da.push_back(s.ellipse.semi_major - truth.semi_major);
    sigma_x += s.center_x_sigma / kTrials;
    sigma_y += s.center_y_sigma / kTrials;
    sigma_a += s.semi_major_sigma / kTrials;
    sigma0 += s.sigma0 / kTrials;
  }
  const auto rms = [](const std::vector<double>& v) {  // about the truth: includes bias
    double sum = 0.0;
    for (const double x : v) sum += x * x;
    return std::sqrt(sum / static_cast<double>(v.size()));
  };
  RecordProperty("empirical_x", Num(rms(dx)));
  RecordProperty("reported_x", Num(sigma_x));
  RecordProperty("empirical_y", Num(rms(dy)));
  RecordProperty("reported_y", Num(sigma_y));
  RecordProperty("empirical_a", Num(rms(da)));
  RecordProperty("reported_a", Num(sigma_a));
  EXPECT_NEAR(sigma0, kNoise, 0.1 * kNoise);
  EXPECT_GT(rms(dx) / sigma_x, 0.5) << rms(dx) << " vs " << sigma_x;
  EXPECT_LT(rms(dx) / sigma_x, 2.0) << rms(dx) << " vs " << sigma_x;
  EXPECT_GT(rms(dy) / sigma_y, 0.5) << rms(dy) << " vs " << sigma_y;
  EXPECT_LT(rms(dy) / sigma_y, 2.0) << rms(dy) << " vs " << sigma_y;
  EXPECT_GT(rms(da) / sigma_a, 0.5) << rms(da) << " vs " << sigma_a;
  EXPECT_LT(rms(da) / sigma_a, 2.0) << rms(da) << " vs " << sigma_a;
}

TEST(RefineEllipseGeometric, ResistsOutliersWithRobustLoss) {
  const Ellipse truth{{0.0, 0.0}, 30.0, 20.0, 0.3};
  std::mt19937 rng(11);
  std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.0, 2.0 * kPi, 100, 0.2, &rng);
  std::uniform_real_distribution<double> far(-25.0, 25.0);
  for (int i = 0; i < 15; ++i) points.emplace_back(far(rng), far(rng));  // 13% clutter
  GeometricFitOptions options;
  options.loss = RobustLoss::kCauchy;
  options.loss_scale = 0.5;
  const Ellipse start{{1.0, -1.0}, 28.0, 21.0, 0.2};
  const EllipseFitSummary robust = RefineEllipseGeometric(start, points, options);
  options.loss = RobustLoss::kNone;
  const EllipseFitSummary plain = RefineEllipseGeometric(start, points, options);
  EXPECT_LT((robust.ellipse.center - truth.center).norm(), 0.2) << robust.BriefReport();
  EXPECT_NEAR(robust.ellipse.semi_major, truth.semi_major, 0.2);
  EXPECT_GT((plain.ellipse.center - truth.center).norm() +
                std::abs(plain.ellipse.semi_major - truth.semi_major),
            0.5)
      << plain.BriefReport();
}

TEST(RefineEllipseGeometric, CircleHasUnobservableAngle) {
  const Ellipse circle{{10.0, 20.0}, 15.0, 15.0, 0.0};
  std::mt19937 rng(5);
  const std::vector<Eigen::Vector2d> points = SampleArc(circle, 0.0, 2.0 * kPi, 64, 0.0, &rng);
  const EllipseFitSummary s = RefineEllipseGeometric({{11.0, 19.0}, 16.0, 14.5, 0.4}, points);
  EXPECT_TRUE(s.converged) << s.BriefReport();
  EXPECT_NEAR(s.ellipse.semi_major, 15.0, 1e-6);
  EXPECT_NEAR(s.ellipse.semi_minor, 15.0, 1e-6);
  ASSERT_TRUE(s.covariance_valid);
  EXPECT_TRUE(std::isinf(s.angle_sigma)) << s.angle_sigma;
  EXPECT_TRUE(std::isfinite(s.center_x_sigma));
}

// One point's orthogonal distance as its own Ceres residual block (the robust loss, if any, on
// the block): the textbook formulation the fit's single block must agree with.
class Distance : public ceres::SizedCostFunction<1, 4, 1> {
 public:
  explicit Distance(const Eigen::Vector2d& p) : p_(p) {}
  bool Evaluate(double const* const* x, double* residual, double** jacobians) const override {
    const Ellipse at{{x[0][0], x[0][1]}, x[0][2], x[0][3], x[1][0]};
    if (!(at.semi_major > 0.0 && at.semi_minor > 0.0)) return false;
    Eigen::Matrix<double, 5, 1> g;
    residual[0] = at.SignedDistanceWithGradient(p_, &g);
    if (jacobians != nullptr && jacobians[0] != nullptr) {
      for (int i = 0; i < 4; ++i) jacobians[0][i] = g(i);
    }
    if (jacobians != nullptr && jacobians[1] != nullptr) jacobians[1][0] = g(4);
    return std::isfinite(residual[0]);
  }

 private:
  Eigen::Vector2d p_;
};

// One Distance block per point on (shape, angle), all with the options' loss (owned by
// `problem`).
void AddPerPointBlocks(const std::vector<Eigen::Vector2d>& points,
                       const GeometricFitOptions& options, double* shape, double* angle,
                       ceres::Problem* problem) {
  ceres::LossFunction* loss = nullptr;
  if (options.loss == RobustLoss::kHuber) loss = new ceres::HuberLoss(options.loss_scale);
  if (options.loss == RobustLoss::kCauchy) loss = new ceres::CauchyLoss(options.loss_scale);
  for (const Eigen::Vector2d& p : points) {
    problem->AddResidualBlock(new Distance(p), loss, shape, angle);
  }
}

// Ceres' own covariance of the fit at `e` (DENSE_SVD, the fit's robust loss), scaled by sigma0^2
// as RefineEllipseGeometric scales its own: the reference the summary's covariance must match.
// With `hold_angle` the angle block is held constant (angle row and column NaN).
std::optional<Eigen::Matrix<double, 5, 5>> CeresCovariance(
    const Ellipse& e, const std::vector<Eigen::Vector2d>& points,
    const GeometricFitOptions& options, double sigma0, bool hold_angle) {
  double shape[4] = {e.center.x(), e.center.y(), e.semi_major, e.semi_minor};
  double angle[1] = {e.angle};
  ceres::Problem problem;
  AddPerPointBlocks(points, options, shape, angle, &problem);
  if (hold_angle) problem.SetParameterBlockConstant(angle);
  ceres::Covariance::Options cov_options;
  cov_options.algorithm_type = ceres::DENSE_SVD;
  ceres::Covariance covariance(cov_options);
  std::vector<std::pair<const double*, const double*>> blocks = {{shape, shape}};
  if (!hold_angle) blocks.insert(blocks.end(), {{shape, angle}, {angle, angle}});
  if (!covariance.Compute(blocks, &problem)) return std::nullopt;
  Eigen::Matrix<double, 4, 4, Eigen::RowMajor> shape_shape;
  Eigen::Matrix<double, 5, 5> out =
      Eigen::Matrix<double, 5, 5>::Constant(std::numeric_limits<double>::quiet_NaN());
  covariance.GetCovarianceBlock(shape, shape, shape_shape.data());
  out.topLeftCorner<4, 4>() = shape_shape;
  if (!hold_angle) {
    Eigen::Matrix<double, 4, 1> shape_angle;
    covariance.GetCovarianceBlock(shape, angle, shape_angle.data());
    covariance.GetCovarianceBlock(angle, angle, &out(4, 4));
    out.block<4, 1>(0, 4) = shape_angle;
    out.block<1, 4>(4, 0) = shape_angle.transpose();
  }
  return out * (sigma0 * sigma0);
}

// Fits 128 points on the arc [t0, t1) of `truth` with `noise` [px] plus `outliers` clutter
// points from `start` and checks the summary's covariance against Ceres' on the same problem.
void ExpectCovarianceEqualsCeres(const Ellipse& truth, double t0, double t1, double noise,
                                 int outliers, RobustLoss loss, double loss_scale,
                                 const Ellipse& start, std::mt19937* rng) {
  std::vector<Eigen::Vector2d> points = SampleArc(truth, t0, t1, 128, noise, rng);
  std::uniform_real_distribution<double> clutter(-0.5, 0.5);
  for (int i = 0; i < outliers; ++i) {
    points.push_back(truth.PointAt(t0 + (t1 - t0) * (0.5 + clutter(*rng))) +
                     Eigen::Vector2d(4.0 * clutter(*rng), 4.0 * clutter(*rng)));
  }
  GeometricFitOptions options;
  options.loss = loss;
  options.loss_scale = loss_scale;
  const EllipseFitSummary s = RefineEllipseGeometric(start, points, options);
  ASSERT_TRUE(s.converged) << s.BriefReport();
  ASSERT_TRUE(s.covariance_valid) << s.BriefReport();
  const bool circle = truth.semi_major == truth.semi_minor;
  EXPECT_EQ(std::isinf(s.covariance(4, 4)), circle) << s.covariance(4, 4);
  const std::optional<Eigen::Matrix<double, 5, 5>> reference =
      CeresCovariance(s.ellipse, points, options, s.sigma0, circle);
  ASSERT_TRUE(reference.has_value());
  const int n = circle ? 4 : 5;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      const double scale = std::sqrt((*reference)(i, i) * (*reference)(j, j));
      EXPECT_NEAR(s.covariance(i, j), (*reference)(i, j), 1e-9 * scale) << i << ", " << j;
    }
  }
}

TEST(RefineEllipseGeometric, CovarianceEqualsCeresDenseSvdCovariance) {
  // The fit computes (J^T J)^-1 of the loss-weighted distances itself; it must equal
  // ceres::Covariance on the same problem to rounding (both from an SVD of J; the relative
  // tolerance 1e-9 is ~1e7 ulp, far below any use of a sigma and far above SVD rounding at
  // these condition numbers).
  std::mt19937 rng(17);
  {
    SCOPED_TRACE("ellipse, full rim, no loss");
    ExpectCovarianceEqualsCeres({{200.0, -120.0}, 50.0, 35.0, 1.1}, 0.0, 2.0 * kPi, 0.5, 0,
                                RobustLoss::kNone, 1.0, {{201.0, -119.0}, 48.0, 36.0, 1.0}, &rng);
  }
  {
    SCOPED_TRACE("ellipse, 3/4 rim with clutter, Huber 0.7 (the detector's loss)");
    ExpectCovarianceEqualsCeres({{30.0, 40.0}, 22.0, 17.0, 0.4}, 0.3, 5.0, 0.4, 12,
                                RobustLoss::kHuber, 0.7, {{30.5, 39.0}, 21.0, 18.0, 0.5}, &rng);
  }
  {
    SCOPED_TRACE("ellipse, half rim with clutter, Cauchy 0.5");
    ExpectCovarianceEqualsCeres({{-500.0, 800.0}, 80.0, 60.0, 2.5}, 1.0, 1.0 + kPi, 0.3, 6,
                                RobustLoss::kCauchy, 0.5, {{-499.0, 801.0}, 79.0, 61.0, 2.4}, &rng);
  }
  {
    SCOPED_TRACE("start with swapped axes: the fit ends with b > a and normalizes");
    ExpectCovarianceEqualsCeres({{0.0, 0.0}, 30.0, 20.0, 0.3}, 0.0, 2.0 * kPi, 0.3, 0,
                                RobustLoss::kHuber, 0.7, {{0.5, -0.5}, 19.0, 31.0, 0.3 + 0.5 * kPi},
                                &rng);
  }
  {
    // Exact points: the angle of a (noisy) circle fit is observable, of an exact one not.
    SCOPED_TRACE("circle: angle held, its variance +inf");
    ExpectCovarianceEqualsCeres({{10.0, 20.0}, 15.0, 15.0, 0.0}, 0.0, 2.0 * kPi, 0.0, 0,
                                RobustLoss::kHuber, 0.7, {{11.0, 19.0}, 16.0, 14.5, 0.4}, &rng);
  }
}

TEST(RefineEllipseGeometric, SameMinimumAsTheLossOnPerPointCeresBlocks) {
  // The fit puts all points in one residual block with the loss applied inside; Ceres with the
  // loss on one block per point minimises the same cost, so both must end at the same ellipse
  // (to the tolerance both are stopped at) and the same cost, with and without clutter beyond
  // the loss' scale.
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> clutter(-0.5, 0.5);
  const Ellipse truth{{40.0, -25.0}, 24.0, 16.0, 0.7};
  for (const RobustLoss loss : {RobustLoss::kNone, RobustLoss::kHuber, RobustLoss::kCauchy}) {
    std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.2, 4.8, 120, 0.3, &rng);
    for (int i = 0; i < 15; ++i) {
      points.push_back(truth.PointAt(2.5 + 4.0 * clutter(rng)) +
                       Eigen::Vector2d(5.0 * clutter(rng), 5.0 * clutter(rng)));
    }
    GeometricFitOptions options;
    options.loss = loss;
    options.loss_scale = 0.7;
    options.function_tolerance = options.parameter_tolerance = 1e-12;
    const Ellipse start{{41.0, -24.0}, 22.5, 17.0, 0.6};
    const EllipseFitSummary fit = RefineEllipseGeometric(start, points, options);
    ASSERT_TRUE(fit.converged) << fit.BriefReport();

    double shape[4] = {start.center.x(), start.center.y(), start.semi_major, start.semi_minor};
    double angle[1] = {start.angle};
    ceres::Problem problem;
    AddPerPointBlocks(points, options, shape, angle, &problem);
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.function_tolerance = solver.parameter_tolerance = solver.gradient_tolerance = 1e-14;
    solver.max_num_iterations = 200;
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    ASSERT_EQ(summary.termination_type, ceres::CONVERGENCE) << summary.BriefReport();
    const Ellipse reference =
        Ellipse{{shape[0], shape[1]}, shape[2], shape[3], angle[0]}.Normalized();
    SCOPED_TRACE(static_cast<int>(loss));
    EXPECT_NEAR(fit.ellipse.center.x(), reference.center.x(), 1e-6);
    EXPECT_NEAR(fit.ellipse.center.y(), reference.center.y(), 1e-6);
    EXPECT_NEAR(fit.ellipse.semi_major, reference.semi_major, 1e-6);
    EXPECT_NEAR(fit.ellipse.semi_minor, reference.semi_minor, 1e-6);
    EXPECT_NEAR(fit.ellipse.angle, reference.angle, 1e-7);
    const double dof = static_cast<double>(points.size()) - 5.0;
    EXPECT_NEAR(fit.sigma0, std::sqrt(2.0 * summary.final_cost / dof), 1e-9);
  }
}

TEST(RefineEllipseGeometric, ReportsFailureWithoutThrowing) {
  const Ellipse start{{0.0, 0.0}, 10.0, 5.0, 0.0};
  const EllipseFitSummary few = RefineEllipseGeometric(start, {{10, 0}, {0, 5}, {-10, 0}});
  EXPECT_FALSE(few.converged);
  EXPECT_EQ(few.num_points, 3);
  EXPECT_NE(few.message.find("at least 5"), std::string::npos) << few.message;
  EXPECT_EQ(few.ellipse.semi_major, 10.0);
  const EllipseFitSummary bad = RefineEllipseGeometric(
      {{0.0, 0.0}, 10.0, 0.0, 0.0}, {{10, 0}, {0, 5}, {-10, 0}, {0, -5}, {7, 3.5}});
  EXPECT_FALSE(bad.converged);
  EXPECT_NE(bad.message.find("positive axes"), std::string::npos) << bad.message;
  EXPECT_NE(bad.BriefReport().find("NOT converged"), std::string::npos);
}

TEST(GeometricFitOptions, CheckNamesTheBadField) {
  EXPECT_NO_THROW(GeometricFitOptions{}.Check());
  const auto expect_field = [](const GeometricFitOptions& options, const std::string& field) {
    try {
      options.Check();
      ADD_FAILURE() << "no error for " << field;
    } catch (const Error& error) {
      EXPECT_NE(std::string(error.what()).find(field), std::string::npos) << error.what();
    }
  };
  GeometricFitOptions o;
  o.loss_scale = 0.0;
  expect_field(o, "loss_scale");
  o = {};
  o.loss_scale = std::numeric_limits<double>::quiet_NaN();
  expect_field(o, "loss_scale");
  o = {};
  o.max_num_iterations = 0;
  expect_field(o, "max_num_iterations");
  o = {};
  o.function_tolerance = -1.0;
  expect_field(o, "function_tolerance");
  o = {};
  o.parameter_tolerance = 0.0;
  expect_field(o, "parameter_tolerance");
  o = {};
  o.num_threads = 0;
  expect_field(o, "num_threads");
  o = {};
  o.max_num_iterations = -3;
  EXPECT_THROW(RefineEllipseGeometric(Ellipse{{0, 0}, 2, 1, 0}, {}, o), Error);
}

TEST(EllipseFitSimilarity, IsOneForPointsOnACircle) {
  const Ellipse circle{{-3.0, 4.0}, 12.0, 12.0, 0.0};
  std::mt19937 rng(2);
  const std::vector<Eigen::Vector2d> points = SampleArc(circle, 0.1, 1.7, 37, 0.0, &rng);
  EXPECT_NEAR(EllipseFitSimilarity(circle, points), 1.0, 1e-12);
  EXPECT_TRUE(std::isnan(EllipseFitSimilarity(circle, {})));
}

TEST(EllipseFitSimilarity, ExceedsOneForPointsOutsideTheEllipse) {
  const Ellipse circle{{0.0, 0.0}, 10.0, 10.0, 0.0};
  const Ellipse larger{{0.0, 0.0}, 11.0, 11.0, 0.0};
  std::mt19937 rng(2);
  const std::vector<Eigen::Vector2d> points = SampleArc(larger, 0.0, 2.0 * kPi, 90, 0.0, &rng);
  EXPECT_NEAR(EllipseFitSimilarity(circle, points), 1.1, 1e-12);
}

TEST(EllipseFitSimilarity, VictoriaCraterFitIsNearOne) {
  // Victoria crater (ch. 2.2.1): a = 406.3 m, b = 382.5 m, EFS 0.9987 from 7,375 Canny edge
  // points on HiRISE. Map coordinates near 2.05 S, 5.5 W; edges with 0.5 m (2 px) noise.
  const Ellipse truth{{-326018.0, -121553.0}, 406.3, 382.5, 0.6};
  std::mt19937 rng(1988);
  const std::vector<Eigen::Vector2d> points = SampleArc(truth, 0.0, 2.0 * kPi, 7375, 0.5, &rng);
  const std::optional<Ellipse> direct = FitEllipseDirect(points);
  ASSERT_TRUE(direct.has_value());
  const EllipseFitSummary fit = RefineEllipseGeometric(*direct, points);
  ASSERT_TRUE(fit.converged) << fit.BriefReport();
  const double efs = EllipseFitSimilarity(fit.ellipse, points);
  RecordProperty("efs", Num(efs));
  RecordProperty("fit", fit.BriefReport());
  EXPECT_GE(efs, 0.998);
  EXPECT_LE(efs, 1.002);
  EXPECT_NEAR(fit.ellipse.semi_major / truth.semi_major, 1.0, 0.01);
  EXPECT_NEAR(fit.ellipse.semi_minor / truth.semi_minor, 1.0, 0.01);
  EXPECT_NEAR(direct->semi_major / truth.semi_major, 1.0, 0.01);
  EXPECT_NEAR(direct->semi_minor / truth.semi_minor, 1.0, 0.01);
  EXPECT_LT((fit.ellipse.center - truth.center).norm(), 0.1);
  EXPECT_NEAR(fit.ellipse.Eccentricity(), 0.34, 0.01);
  EXPECT_NEAR(fit.sigma0, 0.5, 0.02);
  EXPECT_NEAR(EdgeCoverage(fit.ellipse, points, 2.0), 1.0, 1e-12);
}

TEST(EdgeCoverage, CountsSectorsHoldingRimPoints) {
  const Ellipse e{{50.0, 50.0}, 40.0, 30.0, 0.9};
  std::mt19937 rng(4);
  const std::vector<Eigen::Vector2d> full = SampleArc(e, 0.0, 2.0 * kPi, 360, 0.3, &rng);
  EXPECT_DOUBLE_EQ(EdgeCoverage(e, full, 1.5), 1.0);
  const std::vector<Eigen::Vector2d> half = SampleArc(e, 0.05, 0.05 + kPi, 180, 0.3, &rng);
  EXPECT_NEAR(EdgeCoverage(e, half, 1.5), 0.5, 1.0 / 36.0 + 1e-12);
  const Ellipse bigger{{50.0, 50.0}, 60.0, 50.0, 0.9};
  const std::vector<Eigen::Vector2d> far = SampleArc(bigger, 0.0, 2.0 * kPi, 360, 0.0, &rng);
  EXPECT_DOUBLE_EQ(EdgeCoverage(e, far, 1.5), 0.0);
  EXPECT_DOUBLE_EQ(EdgeCoverage(e, {}, 1.5), 0.0);
  EXPECT_THROW(EdgeCoverage(e, full, 1.5, 0), Error);
  EXPECT_THROW(EdgeCoverage(e, full, -1.0), Error);
}

}  // namespace
}  // namespace areomap
