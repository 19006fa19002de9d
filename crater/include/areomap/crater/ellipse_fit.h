// Fitting ellipses to crater-rim edge points and measuring how well they fit.
//
// Points and results share one 2D frame: pixel coordinates of an image or map coordinates
// [m] of a georeferenced raster (see ellipse.h); distances, residuals and their 1-sigma are
// in that frame's unit, angles in radians.
//
// - FitEllipseDirect: algebraic fit through OpenCV (cv::fitEllipseDirect and siblings), fast
//   and closed-form but biased on partial arcs. Use it to start RefineEllipseGeometric.
// - RefineEllipseGeometric: orthogonal-distance (geometric) least squares with Ceres, the
//   maximum-likelihood fit for isotropic edge noise, with 1-sigma from the covariance.
// - EllipseFitSimilarity: the dissertation's quality figure (eq. 2.1); EdgeCoverage: how much
//   of the rim the points cover.
//
// Per-fit failures (too few points, degenerate geometry, no convergence) are reported as
// std::nullopt or a flag, never as an exception; only bad options throw areomap::Error.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "areomap/crater/ellipse.h"

namespace areomap {

// Algebraic ellipse fit through OpenCV: cv::fitEllipseDirect (Fitzgibbon, Pilu and Fisher
// 1999, always an ellipse), guarded against OpenCV 4.6's defects: its singularity test is
// not scale-invariant, so beyond ~150 points it silently returns cv::fitEllipse's
// unconstrained fit, and on near-exact points its eigenvector is off by ~1e-3 of the size.
// cv::fitEllipseAMS and cv::fitEllipse are therefore run too, and the valid candidate with
// the smallest RMS Sampson distance (orthogonal distance to first order) is returned (the
// direct fit on ties). Points are
// centred and scaled to unit RMS radius before OpenCV sees them (it works in float), so
// noise-free points give the ellipse to ~1e-7 of its size wherever it lies. Algebraic fits
// are biased toward small ellipses on partial, noisy arcs: use the result to start
// RefineEllipseGeometric. Deterministic (OpenCV's global RNG is seeded, then restored).
// Non-finite points are ignored. nullopt for fewer than 5 finite points or when no
// candidate is a proper ellipse (collinear points, non-finite or non-positive axes, axis
// ratio > 1e6, major axis > 1e6 times the point spread).
std::optional<Ellipse> FitEllipseDirect(const std::vector<Eigen::Vector2d>& points);

// One algebraic fit (cv::fitEllipseAMS) instead of FitEllipseDirect's comparison of three:
// about 3x cheaper, accurate to ~1e-3 of the size on near-exact points, for screening
// hypotheses whose final fit is geometric. AMS sees at most kFastFitMaxPoints of the finite
// points, evenly spread along their order (beyond ~160 OpenCV 4.6 silently swaps AMS for its
// unconstrained fit at ~7x the cost). Falls back to FitEllipseDirect on all points when AMS
// gives no proper ellipse. Same frame, scaling, determinism and failure rules as
// FitEllipseDirect.
constexpr size_t kFastFitMaxPoints = 128;
std::optional<Ellipse> FitEllipseFast(const std::vector<Eigen::Vector2d>& points);

enum class RobustLoss {
  kNone,    // plain least squares
  kHuber,   // quadratic below loss_scale, linear above
  kCauchy,  // log(1 + (r/loss_scale)^2): strong down-weighting of far outliers
};

struct GeometricFitOptions {
  RobustLoss loss = RobustLoss::kHuber;
  // Residual where the robust loss departs from least squares [point unit, px for image
  // points]; about 2-3 times the edge noise (1 px suits sub-pixel Canny edges).
  double loss_scale = 1.0;
  int max_num_iterations = 100;        // Levenberg-Marquardt iterations (> 0)
  double function_tolerance = 1e-12;   // relative cost change that counts as converged (> 0)
  double parameter_tolerance = 1e-12;  // relative step size that counts as converged (> 0)
  bool compute_covariance = true;      // fill the summary's covariance and 1-sigma
  int num_threads = 1;                 // Ceres threads (> 0); 1 keeps runs reproducible

  // Throws areomap::Error naming the first field that breaks its rule.
  void Check() const;
};

struct EllipseFitSummary {
  Ellipse ellipse;         // refined and Normalized(); the initial ellipse when the fit failed
  int num_points = 0;      // finite points used
  int num_iterations = 0;  // Ceres iterations
  bool converged = false;  // Ceres reported convergence and the result is a valid ellipse
  std::string message;     // why the fit stopped (Ceres' message or the failed precondition)

  double initial_rms_residual = 0.0;  // RMS orthogonal distance of the initial ellipse
  double rms_residual = 0.0;          // RMS orthogonal distance after the fit [point unit]
  // A-posteriori standard deviation of unit weight: sqrt(2 * robust cost / (N - 5)); equals
  // the RMS orthogonal residual (with N - 5 degrees of freedom) when no point is down-weighted.
  double sigma0 = 0.0;

  // Covariance of (center.x, center.y, semi_major, semi_minor, angle): (J^T J)^-1 of the
  // loss-weighted distances at the solution times sigma0^2, as ceres::Covariance (DENSE_SVD)
  // computes it on the fit's problem (equal to rounding, tests/crater). NaN where not computed.
  // When the angle is unobservable (a circle within numerical precision) the other four come
  // from the Jacobian of the centre and axes alone at the same solution (the angle held), and
  // the angle's variance is +inf (its covariances with the others NaN).
  Eigen::Matrix<double, 5, 5> covariance;
  bool covariance_valid = false;
  double center_x_sigma = 0.0;    // 1-sigma [point unit]
  double center_y_sigma = 0.0;    // 1-sigma [point unit]
  double semi_major_sigma = 0.0;  // 1-sigma [point unit]
  double semi_minor_sigma = 0.0;  // 1-sigma [point unit]
  double angle_sigma = 0.0;       // 1-sigma [rad]

  // One line: points, convergence, iterations, RMS before/after, sigma0 and 1-sigma values.
  std::string BriefReport() const;
};

// Orthogonal-distance least squares: minimises sum_k rho(d_k^2) over (center, a, b, angle),
// where d_k is the exact orthogonal distance of point k to the current ellipse
// (Ellipse::SignedDistance) and rho the chosen robust loss. The Jacobian is analytic
// (Ellipse::SignedDistanceGradient, exact by the envelope theorem), so each point costs one
// distance solve per evaluation. All points form one Ceres residual block, the loss applied
// inside it as residuals sign(d) sqrt(rho(d^2)) (the same cost and gradient as the loss on
// per-point blocks, at a fraction of Ceres' per-block overhead). Needs >= 5 finite points
// (non-finite ones are ignored) and an initial ellipse with positive finite axes, e.g. from
// FitEllipseDirect; otherwise returns converged = false, the initial ellipse and a message. Throws
// areomap::Error only for invalid options.
EllipseFitSummary RefineEllipseGeometric(const Ellipse& initial,
                                         const std::vector<Eigen::Vector2d>& points,
                                         const GeometricFitOptions& options = {});

// Ellipse-Fit-Similarity, eq. 2.1 of the dissertation (ch. 2.2.1):
//   EFS = (1/N) sum_k Dis_k / R_avg,  Dis_k = |p_k - center|,  R_avg = (a + b) / 2.
// It is exactly 1 for points on a circle fitted by that circle and close to 1 for a good fit
// of a near-circular rim (Victoria crater: 0.9987). It is not bounded by 1: points outside
// the ellipse push it above 1, points inside below, and for an elongated ellipse even points
// exactly on the curve give a value off 1 that depends on how they spread around the rim
// (+2.3e-4 for Victoria's axes with points evenly spaced in eccentric anomaly). It measures
// radial agreement only, and errors of opposite sign cancel; use rms_residual for the
// shape and EdgeCoverage for completeness. NaN for no points or an ellipse without positive axes.
double EllipseFitSimilarity(const Ellipse& e, const std::vector<Eigen::Vector2d>& points);

// Fraction in [0, 1] of `bins` equal sectors of eccentric anomaly around the ellipse
// (ClosestParameter) that hold at least one point within max_distance [point unit] of the
// curve: 1 for a complete rim, about 0.5 for a half arc. 0 for no points or an ellipse without
// positive axes. Throws areomap::Error for bins < 1 or a negative or non-finite max_distance.
double EdgeCoverage(const Ellipse& e, const std::vector<Eigen::Vector2d>& points,
                    double max_distance, int bins = 36);

}  // namespace areomap
