#include "rim_fit.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Dense>

#include "areomap/crater/ellipse_fit.h"
#include "areomap/map/numbers.h"
#include "bilinear_sample.h"
#include "edge_point.h"
#include "ring_sampler.h"

namespace areomap::internal {
namespace {

constexpr int kCoverageBins = 36;
constexpr size_t kMaxFitPoints = 128;
// Robust loop: reject when the first (most tolerant) support covers less than this share of
// min_coverage; stop refitting once centre and axes move less than kConvergedShift [px] together.
constexpr double kEarlyCoverageShare = 0.75;
constexpr double kConvergedShift = 0.05;

// Edges within `tolerance` of the ellipse whose normals are aligned with its normal and, with a
// sun, whose polarity fits a bowl.
std::vector<Eigen::Vector2d> GatherSupport(const RimEdges& edges, const Ellipse& e,
                                           double tolerance,
                                           const std::optional<Eigen::Vector2d>& sun,
                                           double* mean_strength = nullptr) {
  double strength_sum = 0.0;
  std::vector<Eigen::Vector2d> support;
  const double reach = e.semi_major + tolerance + 1.0;
  const int c0 = std::max(0, static_cast<int>(std::floor(e.center.x() - reach)));
  const int c1 = std::min(edges.cols - 1, static_cast<int>(std::ceil(e.center.x() + reach)));
  const int r0 = std::max(0, static_cast<int>(std::floor(e.center.y() - reach)));
  const int r1 = std::min(edges.rows - 1, static_cast<int>(std::ceil(e.center.y() + reach)));
  const double cs = std::cos(e.angle), sn = std::sin(e.angle);
  const double a2 = e.semi_major * e.semi_major, b2 = e.semi_minor * e.semi_minor;
  // The distance test below is |p - c| |1 - 1/rho| = R |rho - 1| with R, the centre's distance
  // to the ellipse along the ray, at least the smaller semi-axis: points with rho outside
  // 1 -/+ tolerance / that axis fail it, and are skipped on rho^2 without square roots (the
  // axis shrunk by 1e-9 keeps rounding on the safe side).
  const double band = tolerance / (std::min(e.semi_major, e.semi_minor) * (1.0 - 1e-9));
  const double rho2_max = (1.0 + band) * (1.0 + band);
  const double rho2_min = band < 1.0 ? (1.0 - band) * (1.0 - band) : 0.0;
  for (int r = r0; r <= r1; ++r) {
    const int last = edges.row_start[static_cast<size_t>(r) + 1];
    for (int i = edges.FirstInRow(r, c0); i < last && edges.column[static_cast<size_t>(i)] <= c1;
         ++i) {
      const RimEdgePoint& p = edges.points[static_cast<size_t>(i)];
      const Eigen::Vector2d d = Pos(p) - e.center;
      const double u = cs * d.x() + sn * d.y(), v = -sn * d.x() + cs * d.y();
      const double rho2 = u * u / a2 + v * v / b2;
      if (rho2 > rho2_max || rho2 < rho2_min) continue;
      const double rho = std::sqrt(rho2);
      const double dist = d.norm();
      if (rho <= 1e-9 || std::abs(dist - dist / rho) > tolerance) continue;
      const Eigen::Vector2d g_local(u / a2, v / b2);
      const Eigen::Vector2d g =
          Eigen::Vector2d(cs * g_local.x() - sn * g_local.y(), sn * g_local.x() + cs * g_local.y())
              .normalized();
      const double alignment = Normal(p).dot(g);
      if (std::abs(alignment) < 0.8) continue;
      if (sun && (alignment > 0 ? 1.0 : -1.0) * (d / dist).dot(*sun) < -0.25) continue;
      support.push_back(Pos(p));
      strength_sum += p.strength;
    }
  }
  if (mean_strength) {
    *mean_strength = support.empty() ? 0.0 : strength_sum / static_cast<double>(support.size());
  }
  return support;
}

// Fraction of 36 sectors of polar angle around the centre (in the ellipse's frame) holding a
// point: EdgeCoverage without the distance solves, for points already near the curve.
double AngularCoverage(const Ellipse& e, const std::vector<Eigen::Vector2d>& points) {
  std::array<bool, kCoverageBins> hit{};
  const double cs = std::cos(e.angle), sn = std::sin(e.angle);
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d d = p - e.center;
    const double u = (cs * d.x() + sn * d.y()) / e.semi_major;
    const double v = (-sn * d.x() + cs * d.y()) / e.semi_minor;
    const double t = std::atan2(v, u) + std::numbers::pi;
    hit[static_cast<size_t>(std::clamp(
        static_cast<int>(t / (2.0 * std::numbers::pi) * kCoverageBins), 0, kCoverageBins - 1))] =
        true;
  }
  return static_cast<double>(std::count(hit.begin(), hit.end(), true)) / kCoverageBins;
}

// RMS of the radial distances |p - c| (1 - 1/rho) to the ellipse: the orthogonal distance to
// first order for points near a near-circular rim.
double RadialRms(const Ellipse& e, const std::vector<Eigen::Vector2d>& points) {
  const double cs = std::cos(e.angle), sn = std::sin(e.angle);
  double sum = 0.0;
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d d = p - e.center;
    const double u = (cs * d.x() + sn * d.y()) / e.semi_major;
    const double v = (-sn * d.x() + cs * d.y()) / e.semi_minor;
    const double rho = std::max(Eigen::Vector2d(u, v).norm(), 1e-12);  // not std::hypot: u, v ~ 1
    const double r = d.norm() * (1.0 - 1.0 / rho);
    sum += r * r;
  }
  return points.empty() ? kNaN : std::sqrt(sum / static_cast<double>(points.size()));
}

}  // namespace

// Unit vector towards the sun in pixel coordinates (x right, y down), azimuth clockwise from up.
std::optional<Eigen::Vector2d> SunVector(const CraterDetectorOptions& o, RimSource source) {
  if (source != RimSource::kImage || !o.sun_azimuth_deg) return std::nullopt;
  const double az = *o.sun_azimuth_deg * std::numbers::pi / 180.0;
  return Eigen::Vector2d(std::sin(az), -std::cos(az));
}

std::optional<Ellipse> SaneFit(const std::vector<Eigen::Vector2d>& points, const Ellipse& prior,
                               double max_axis_ratio) {
  const std::optional<Ellipse> fit = FitEllipseFast(points);
  if (!fit) return std::nullopt;
  const double r = prior.MeanRadius();
  if ((fit->center - prior.center).norm() > 0.35 * r + 1.0) return std::nullopt;
  if (std::abs(fit->MeanRadius() / r - 1.0) > 0.35) return std::nullopt;
  if (fit->semi_major > max_axis_ratio * fit->semi_minor) return std::nullopt;
  return fit;
}

SignatureValues Signature(const cv::Mat& raster, RimSource source, const Ellipse& e,
                          const std::optional<Eigen::Vector2d>& sun) {
  constexpr int kSamples = kRingSamples;
  const RingSampler ring(e);
  SignatureValues out;
  if (source == RimSource::kImage) {
    if (!sun) return out;
    RingStats toward, away, outside;
    double sw = 0, sv = 0, sww = 0, svv = 0, swv = 0;
    int n = 0;
    for (double rho : {0.3, 0.45, 0.6, 0.75}) {
      for (int k = 0; k < kSamples; ++k) {
        const Eigen::Vector2d p = ring.Point(rho, k);
        const double w = (p - e.center).normalized().dot(*sun);
        const double v = internal::SampleBilinear(raster, p.x(), p.y());
        if (!std::isfinite(v)) continue;
        if (w > 0.3) toward.Add(v);
        if (w < -0.3) away.Add(v);
        sw += -w;
        sv += v;
        sww += w * w;
        svv += v * v;
        swv += -w * v;
        ++n;
      }
    }
    for (double rho : {1.3, 1.6, 1.9}) {
      for (int k = 0; k < kSamples; ++k) {
        const Eigen::Vector2d p = ring.Point(rho, k);
        outside.Add(internal::SampleBilinear(raster, p.x(), p.y()));
      }
    }
    const double scale = outside.n > 4 ? outside.Std() : kNaN;
    if (toward.n == 0 || away.n == 0 || !(scale > 0.0) || n < 8) return out;
    out.value = (away.Mean() - toward.Mean()) / scale;
    const double cov = swv / n - (sw / n) * (sv / n);
    const double var_w = sww / n - (sw / n) * (sw / n), var_v = svv / n - (sv / n) * (sv / n);
    out.correlation = var_w > 0 && var_v > 0 ? cov / std::sqrt(var_w * var_v) : kNaN;
    return out;
  }
  RingStats rim, inner;
  for (int k = 0; k < kSamples; ++k) {
    const Eigen::Vector2d p = ring.Point(1.0, k);
    rim.Add(internal::SampleBilinear(raster, p.x(), p.y()));
    for (double rho : {0.0, 0.25, 0.5}) {
      const Eigen::Vector2d q = ring.Point(rho, k);
      inner.Add(internal::SampleBilinear(raster, q.x(), q.y()));
    }
  }
  if (rim.n == 0 || inner.n == 0) return out;
  out.value = (rim.Mean() - inner.Mean()) / (2.0 * e.MeanRadius());
  return out;
}

// `slack` < 1 relaxes the threshold (a pre-screen on a rough ellipse).
bool SignaturePasses(const SignatureValues& s, RimSource source, const CraterDetectorOptions& o,
                     double slack) {
  if (source == RimSource::kDtm) return s.value / o.dtm_posting >= slack * o.min_depth_ratio;
  if (!o.sun_azimuth_deg) return true;
  return s.value >= slack * o.min_shading_contrast;
}

namespace {

// The trimmed robust loop from `start`: up to three direct fits, each on the edges gathered
// around the previous ellipse in a narrowing band. None when the support is too thin or, on
// the first (most tolerant) gathering, covers too little of the rim.
std::optional<Ellipse> RobustDirectFit(const RimEdges& edges, const Ellipse& start,
                                       const CraterDetectorOptions& o,
                                       const std::optional<Eigen::Vector2d>& sun) {
  Ellipse e = start;
  std::vector<Eigen::Vector2d> support;
  for (int iteration = 0; iteration < 3; ++iteration) {
    const double tolerance = std::max(1.5, (iteration == 0 ? 0.12 : 0.06) * e.MeanRadius());
    support = GatherSupport(edges, e, tolerance, sun);
    if (support.size() < 8) return std::nullopt;
    // Early rejection: the first gathering is the most tolerant one; a rim covering far fewer
    // sectors than required cannot pass the final coverage check on the tighter band.
    if (iteration == 0 && AngularCoverage(e, support) < kEarlyCoverageShare * o.min_coverage) {
      return std::nullopt;
    }
    const std::optional<Ellipse> fit = SaneFit(support, e, o.max_axis_ratio);
    if (!fit) break;
    const double moved = (fit->center - e.center).norm() +
                         std::abs(fit->semi_major - e.semi_major) +
                         std::abs(fit->semi_minor - e.semi_minor);
    e = *fit;
    if (moved < kConvergedShift) break;  // a refit would gather the same edges
  }
  return e;
}

// The direct fit's rim on the final tight band, with the values of its cheap checks.
struct DirectRim {
  Ellipse ellipse;
  std::vector<Eigen::Vector2d> support;
  double edge_contrast = 0.0;
  SignatureValues signature;
  double coverage = 0.0;
};

// Cheap checks before the geometric fit: edge sharpness, bowl signature, sector coverage. None
// when one fails.
std::optional<DirectRim> CheckDirectRim(const cv::Mat& raster, const RimEdges& edges,
                                        RimSource source, const Ellipse& e,
                                        const CraterDetectorOptions& o,
                                        const std::optional<Eigen::Vector2d>& sun) {
  DirectRim rim;
  rim.ellipse = e;
  double mean_strength = 0.0;
  rim.support = GatherSupport(edges, e, std::max(1.5, 0.04 * e.MeanRadius()), sun, &mean_strength);
  if (rim.support.size() < 8) return std::nullopt;
  rim.edge_contrast = edges.high_threshold > 0.0 ? mean_strength / edges.high_threshold : 0.0;
  if (rim.edge_contrast < o.min_edge_contrast) return std::nullopt;
  rim.signature = Signature(raster, source, e, sun);
  if (!SignaturePasses(rim.signature, source, o)) return std::nullopt;
  rim.coverage = AngularCoverage(e, rim.support);
  if (rim.coverage < o.min_coverage) return std::nullopt;
  return rim;
}

// The geometric (orthogonal distance, Huber) fit from the direct rim: ellipse, sigmas, residual
// and point count; none when it does not converge.
std::optional<CraterDetection> GeometricFit(const DirectRim& rim) {
  GeometricFitOptions fit_options;
  fit_options.loss = RobustLoss::kHuber;
  fit_options.loss_scale = 0.7;
  fit_options.max_num_iterations = 20;
  // The direct fit starts close. Stop at a relative cost change or step of 1e-7: a step of
  // 1e-7 x a tile coordinate (< 3e-4 px) is far below the edges' noise (~0.05 px on the
  // centre), and the fits end 1-2 iterations sooner than at 1e-10, with the same ellipses.
  fit_options.function_tolerance = 1e-7;
  fit_options.parameter_tolerance = 1e-7;
  // The geometric fit costs one distance solve per point and iteration: at most
  // kMaxFitPoints edges, evenly spread along the scan order (the direct fit used them all).
  const std::vector<Eigen::Vector2d>& support = rim.support;
  std::vector<Eigen::Vector2d> fit_points;
  const size_t stride = (support.size() + kMaxFitPoints - 1) / kMaxFitPoints;
  for (size_t i = 0; i < support.size(); i += stride) fit_points.push_back(support[i]);
  const EllipseFitSummary summary = RefineEllipseGeometric(rim.ellipse, fit_points, fit_options);
  if (!summary.converged) return std::nullopt;
  CraterDetection d;
  d.ellipse = summary.ellipse;
  d.center_x_sigma = summary.center_x_sigma;
  d.center_y_sigma = summary.center_y_sigma;
  d.semi_major_sigma = summary.semi_major_sigma;
  d.semi_minor_sigma = summary.semi_minor_sigma;
  d.angle_sigma = summary.angle_sigma;
  d.rms_residual = summary.rms_residual;
  d.num_edge_points = summary.num_points;
  return d;
}

// The direct rim as the result: no sigmas, the residual from radial distances.
CraterDetection DirectFitResult(const DirectRim& rim) {
  CraterDetection d;
  d.ellipse = rim.ellipse;
  d.center_x_sigma = d.center_y_sigma = d.semi_major_sigma = d.semi_minor_sigma = d.angle_sigma =
      kNaN;
  d.rms_residual = RadialRms(rim.ellipse, rim.support);
  d.num_edge_points = static_cast<int>(rim.support.size());
  return d;
}

// Validation of the fitted `d` (started from `start`) on the direct rim's support: shape,
// centre shift, coverage, residual and signature; then its confidence and whether it is
// partial. None when a check fails.
std::optional<CraterDetection> ValidateFit(CraterDetection d, const cv::Mat& raster,
                                           RimSource source, const Ellipse& start,
                                           const DirectRim& rim, const CraterDetectorOptions& o,
                                           const std::optional<Eigen::Vector2d>& sun,
                                           bool geometric) {
  const std::vector<Eigen::Vector2d>& support = rim.support;
  const Ellipse& fitted = d.ellipse;
  if (fitted.semi_major > o.max_axis_ratio * fitted.semi_minor) return std::nullopt;
  if ((fitted.center - start.center).norm() > 0.4 * start.MeanRadius() + 1.0) return std::nullopt;
  d.edge_contrast = rim.edge_contrast;
  d.efs = EllipseFitSimilarity(fitted, support);
  // Without the geometric fit the ellipse is the direct fit's: its values are known.
  d.coverage = geometric ? AngularCoverage(fitted, support) : rim.coverage;
  const SignatureValues signature =
      geometric ? Signature(raster, source, fitted, sun) : rim.signature;
  d.signature = signature.value;
  d.shading_correlation = signature.correlation;
  if (d.coverage < o.min_coverage) return std::nullopt;
  if (d.rms_residual > 0.08 * fitted.MeanRadius() + 0.6) return std::nullopt;
  double strength = 1.0;
  if (source == RimSource::kDtm) {
    const double depth_ratio = d.signature / o.dtm_posting;
    if (!(depth_ratio >= o.min_depth_ratio)) return std::nullopt;
    strength = std::min(1.0, depth_ratio / (3.0 * o.min_depth_ratio));
  } else if (sun) {
    if (!(d.signature >= o.min_shading_contrast)) return std::nullopt;
    strength = std::min(1.0, d.signature / (3.0 * o.min_shading_contrast));
  }
  const double fit_quality = std::exp(-d.rms_residual / (0.05 * fitted.MeanRadius() + 0.5));
  d.confidence = std::clamp(d.coverage * strength * fit_quality, 0.0, 1.0);
  const double reach = fitted.semi_major;
  d.partial = d.coverage < 0.6 || fitted.center.x() - reach < 0 || fitted.center.y() - reach < 0 ||
              fitted.center.x() + reach > raster.cols || fitted.center.y() + reach > raster.rows;
  return d;
}

}  // namespace

std::optional<CraterDetection> FitAndValidate(const cv::Mat& raster, const RimEdges& edges,
                                              RimSource source, const Ellipse& start,
                                              const CraterDetectorOptions& o, bool geometric) {
  const std::optional<Eigen::Vector2d> sun = SunVector(o, source);
  const std::optional<Ellipse> direct = RobustDirectFit(edges, start, o, sun);
  if (!direct) return std::nullopt;
  const std::optional<DirectRim> rim = CheckDirectRim(raster, edges, source, *direct, o, sun);
  if (!rim) return std::nullopt;
  const std::optional<CraterDetection> fit =
      geometric ? GeometricFit(*rim) : std::optional<CraterDetection>(DirectFitResult(*rim));
  if (!fit) return std::nullopt;
  return ValidateFit(*fit, raster, source, start, *rim, o, sun, geometric);
}

}  // namespace areomap::internal
