#include "areomap/crater/ellipse_fit.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iomanip>
#include <limits>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/numbers.h"

namespace areomap {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Direct fits with a larger axis ratio, or a major axis this many times the point spread,
// come from (nearly) collinear points.
constexpr double kMaxAxisRatio = 1e6;

std::vector<Eigen::Vector2d> FinitePoints(const std::vector<Eigen::Vector2d>& points) {
  std::vector<Eigen::Vector2d> finite;
  finite.reserve(points.size());
  for (const Eigen::Vector2d& p : points) {
    if (p.allFinite()) finite.push_back(p);
  }
  return finite;
}

// Sum of squares in point order, then the root of the mean.
double RootMeanSquare(const Eigen::VectorXd& distances) {
  if (distances.size() == 0) return kNaN;
  double sum = 0.0;
  for (const double d : distances) sum += d * d;
  return std::sqrt(sum / static_cast<double>(distances.size()));
}

double RmsDistance(const Ellipse& e, const std::vector<Eigen::Vector2d>& points) {
  Eigen::VectorXd distances(static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) {
    distances(static_cast<Eigen::Index>(i)) = e.SignedDistance(points[i]);
  }
  return RootMeanSquare(distances);
}

// RMS Sampson distance |f| / |grad f| of the points to the ellipse's conic f: the orthogonal
// distance to first order, at a few flops per point. Ranks candidate fits.
double RmsSampsonDistance(const Ellipse& e, const std::vector<Eigen::Vector2d>& points) {
  const ConicCoefficients k = e.ToConic();
  double sum = 0.0;
  for (const Eigen::Vector2d& p : points) {
    const double x = p.x(), y = p.y();
    const double f = k(0) * x * x + k(1) * x * y + k(2) * y * y + k(3) * x + k(4) * y + k(5);
    const double gx = 2.0 * k(0) * x + k(1) * y + k(3), gy = k(1) * x + 2.0 * k(2) * y + k(4);
    const double g2 = gx * gx + gy * gy;
    sum += g2 > 0.0 ? f * f / g2 : 0.0;
  }
  return std::sqrt(sum / static_cast<double>(points.size()));
}

// The orthogonal distances of all points as one residual block; parameters are (cx, cy, a, b)
// and (angle). With a robust loss rho, residual k is sign(d_k) sqrt(rho(d_k^2)): the cost
// 1/2 sum_k rho(d_k^2) is the one Ceres minimises with the loss on per-point blocks, and so is
// its gradient; only the Gauss-Newton curvature of points beyond the loss' scale differs
// (rho'^2 d^2 / rho instead of Ceres' rho' for losses with rho'' <= 0, at most a factor 2 for
// Huber). One block instead of one per point: Ceres' per-block evaluation, loss correction
// and Jacobian bookkeeping were half of the fit's time.
class OrthogonalDistancesCost : public ceres::CostFunction {
 public:
  OrthogonalDistancesCost(const std::vector<Eigen::Vector2d>& points,
                          const ceres::LossFunction* loss)
      : points_(points), loss_(loss) {
    set_num_residuals(static_cast<int>(points.size()));
    mutable_parameter_block_sizes()->assign({4, 1});
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Ellipse e;
    e.center = Eigen::Vector2d(parameters[0][0], parameters[0][1]);
    e.semi_major = parameters[0][2];
    e.semi_minor = parameters[0][3];
    e.angle = parameters[1][0];
    if (!e.HasPositiveAxes()) return false;  // Ceres rejects the step
    const bool with_jacobian =
        jacobians != nullptr && (jacobians[0] != nullptr || jacobians[1] != nullptr);
    for (size_t k = 0; k < points_.size(); ++k) {
      Eigen::Matrix<double, 5, 1> gradient;
      const double d = with_jacobian ? e.SignedDistanceWithGradient(points_[k], &gradient)
                                     : e.SignedDistance(points_[k]);
      if (!std::isfinite(d)) return false;
      double scale = 1.0;  // d(residual) / d(distance)
      residuals[k] = d;
      if (loss_ != nullptr) {
        double rho[3];
        loss_->Evaluate(d * d, rho);
        const double r = std::copysign(std::sqrt(rho[0]), d);
        // sqrt(rho(d^2)) = sqrt(rho'(0)) |d| near 0, where the quotient below is 0 / 0.
        scale = std::abs(r) > 1e-150 ? rho[1] * d / r : std::sqrt(rho[1]);
        residuals[k] = r;
      }
      if (!with_jacobian) continue;
      if (jacobians[0] != nullptr) {
        for (int i = 0; i < 4; ++i)
          jacobians[0][4 * k + static_cast<size_t>(i)] = scale * gradient(i);
      }
      if (jacobians[1] != nullptr) jacobians[1][k] = scale * gradient(4);
    }
    return true;
  }

 private:
  const std::vector<Eigen::Vector2d>& points_;
  const ceres::LossFunction* loss_;
};

ceres::LossFunction* MakeLoss(const GeometricFitOptions& options) {
  switch (options.loss) {
    case RobustLoss::kNone:
      return nullptr;
    case RobustLoss::kHuber:
      return new ceres::HuberLoss(options.loss_scale);
    case RobustLoss::kCauchy:
      return new ceres::CauchyLoss(options.loss_scale);
  }
  return nullptr;
}

// Rows of the distance Jacobian in (cx, cy, a, b, angle) at `e` and the distances (the same
// values as Ellipse::SignedDistance); false where one is not finite (Ceres' covariance fails on
// such a residual block).
bool DistanceJacobian(const Ellipse& e, const std::vector<Eigen::Vector2d>& points,
                      Eigen::Matrix<double, Eigen::Dynamic, 5>* jacobian,
                      Eigen::VectorXd* residuals) {
  if (!e.HasPositiveAxes()) return false;
  jacobian->resize(static_cast<Eigen::Index>(points.size()), 5);
  residuals->resize(static_cast<Eigen::Index>(points.size()));
  for (size_t i = 0; i < points.size(); ++i) {
    Eigen::Matrix<double, 5, 1> gradient;
    const double r = e.SignedDistanceWithGradient(points[i], &gradient);
    if (!std::isfinite(r) || !gradient.allFinite()) return false;
    const Eigen::Index row = static_cast<Eigen::Index>(i);
    (*residuals)(row) = r;
    jacobian->row(row) = gradient.transpose();
  }
  return true;
}

// Whether J^T J of the distances in (center, a, b, angle) is safely regular. Ceres' DENSE_SVD
// covariance fails below a reciprocal condition number of 1e-14 (and logged an error through
// glog when it was used here); a circle's angle is the usual culprit. This test keeps a margin
// of 100.
bool AngleObservable(const Eigen::Matrix<double, Eigen::Dynamic, 5>& jacobian) {
  const Eigen::Matrix<double, 5, 5> jtj = jacobian.transpose() * jacobian;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 5, 5>> solver(jtj);
  if (solver.info() != Eigen::Success) return false;
  const Eigen::Matrix<double, 5, 1>& values = solver.eigenvalues();  // ascending
  return values(4) > 0.0 && values(0) > 1e-12 * values(4);
}

// Weights each row of `jacobian` as Ceres' Problem::Evaluate does with the robust loss (its
// Corrector, for a 1-D residual r: sqrt(rho') (1 - alpha) with alpha = 1 - sqrt(1 + 2 r^2 rho''
// / rho') where rho'' > 0 and r != 0, else sqrt(rho')).
void ApplyLoss(const ceres::LossFunction* loss, const Eigen::VectorXd& residuals,
               Eigen::Matrix<double, Eigen::Dynamic, 5>* jacobian) {
  if (loss == nullptr) return;
  for (Eigen::Index i = 0; i < residuals.size(); ++i) {
    const double sq_norm = residuals(i) * residuals(i);
    double rho[3];
    loss->Evaluate(sq_norm, rho);
    double scale = std::sqrt(rho[1]);
    if (sq_norm != 0.0 && rho[2] > 0.0) scale *= std::sqrt(1.0 + 2.0 * sq_norm * rho[2] / rho[1]);
    jacobian->row(i) *= scale;
  }
}

// (J^T J)^-1 from the SVD of J, as ceres::Covariance's DENSE_SVD algorithm computes it, with
// its failure rule: false where a singular value is below sqrt(1e-14) times the largest.
template <int Cols>
bool InverseNormalMatrix(const Eigen::Matrix<double, Eigen::Dynamic, Cols>& jacobian,
                         Eigen::Matrix<double, Cols, Cols>* inverse) {
  const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, Cols>> svd(jacobian,
                                                                          Eigen::ComputeFullV);
  const Eigen::Matrix<double, Cols, 1>& singular = svd.singularValues();  // descending
  const double min_ratio = std::sqrt(1e-14);  // ceres::Covariance::Options default
  Eigen::Matrix<double, Cols, 1> inverse_squared;
  for (int i = 0; i < Cols; ++i) {
    if (!(singular(i) / singular(0) >= min_ratio)) return false;  // also NaN (J all zero)
    inverse_squared(i) = 1.0 / (singular(i) * singular(i));
  }
  *inverse = svd.matrixV() * inverse_squared.asDiagonal() * svd.matrixV().transpose();
  return true;
}

// Fills *covariance (unscaled: (J^T J)^-1 of the loss-weighted distances, `jacobian` and
// `residuals` from DistanceJacobian at the solution) as ceres::Covariance (DENSE_SVD) on the
// fit's problem would, at a fraction of its cost (no second closest-point solve per point, no
// sparse set-up): false when even the 4-parameter covariance is singular. When the angle is not
// observable it is held and its variance is +inf.
bool ComputeCovariance(Eigen::Matrix<double, Eigen::Dynamic, 5> jacobian,
                       const Eigen::VectorXd& residuals, const ceres::LossFunction* loss,
                       Eigen::Matrix<double, 5, 5>* covariance) {
  covariance->setConstant(kNaN);
  const bool angle_observable = AngleObservable(jacobian);
  ApplyLoss(loss, residuals, &jacobian);
  if (angle_observable) {
    Eigen::Matrix<double, 5, 5> full;
    if (InverseNormalMatrix<5>(jacobian, &full)) {
      *covariance = full;
      return true;
    }
  }
  // The angle of a circle is unobservable: hold it and report the rest.
  Eigen::Matrix<double, 4, 4> shape_shape;
  const Eigen::Matrix<double, Eigen::Dynamic, 4> shape_jacobian = jacobian.leftCols<4>();
  if (!InverseNormalMatrix<4>(shape_jacobian, &shape_shape)) return false;
  covariance->topLeftCorner<4, 4>() = shape_shape;
  (*covariance)(4, 4) = kInf;
  return true;
}

// RotatedRect fitted to points scaled as (p - mean) / spread -> Ellipse in the point frame;
// nullopt when degenerate.
std::optional<Ellipse> FromRotatedRect(const cv::RotatedRect& box, const Eigen::Vector2d& mean,
                                       double spread) {
  // RotatedRect: full axes; `angle` [deg] turns the width axis from +x toward +y.
  const double half_width = 0.5 * static_cast<double>(box.size.width);
  const double half_height = 0.5 * static_cast<double>(box.size.height);
  const double width_angle = static_cast<double>(box.angle) * std::numbers::pi / 180.0;
  Ellipse e;
  e.center = mean + spread * Eigen::Vector2d(box.center.x, box.center.y);
  if (half_width >= half_height) {
    e.semi_major = spread * half_width;
    e.semi_minor = spread * half_height;
    e.angle = WrapAxisAngle(width_angle);
  } else {
    e.semi_major = spread * half_height;
    e.semi_minor = spread * half_width;
    e.angle = WrapAxisAngle(width_angle + 0.5 * std::numbers::pi);
  }
  if (!e.IsValid() || e.semi_minor * kMaxAxisRatio < e.semi_major ||
      e.semi_major > kMaxAxisRatio * spread) {
    return std::nullopt;
  }
  return e;
}

}  // namespace

namespace {

// OpenCV's algebraic fits number `first_method` .. `last_method` (0 direct, 1 AMS, 2 plain) on
// centred and scaled points; the one with the smallest RMS Sampson distance wins.
std::optional<Ellipse> FitEllipseOpenCv(const std::vector<Eigen::Vector2d>& points,
                                        int first_method, int last_method) {
  const std::vector<Eigen::Vector2d> finite = FinitePoints(points);
  if (finite.size() < 5) return std::nullopt;

  // OpenCV takes float points: centre and scale them so float keeps ~7 significant digits
  // of the shape whatever the coordinates' magnitude (map eastings reach 1e6 m).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& p : finite) mean += p;
  mean /= static_cast<double>(finite.size());
  double spread = 0.0;
  for (const Eigen::Vector2d& p : finite) spread += (p - mean).squaredNorm();
  spread = std::sqrt(spread / static_cast<double>(finite.size()));
  if (!(spread > 0.0) || !std::isfinite(spread)) return std::nullopt;
  Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
  for (const Eigen::Vector2d& p : finite) scatter.noalias() += (p - mean) * (p - mean).transpose();
  const Eigen::Vector2d scatter_values =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(scatter).eigenvalues();
  if (!(scatter_values(0) > 1e-12 * scatter_values(1))) return std::nullopt;  // collinear
  std::vector<cv::Point2f> scaled;
  scaled.reserve(finite.size());
  for (const Eigen::Vector2d& p : finite) {
    const Eigen::Vector2d q = (p - mean) / spread;
    scaled.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
  }

  // Some OpenCV versions jitter near-singular inputs with the thread's global RNG: seed it
  // for reproducible fits and give the caller's state back.
  cv::RNG& rng = cv::theRNG();
  const uint64_t saved_state = rng.state;
  std::optional<Ellipse> best;
  double best_rms = std::numeric_limits<double>::infinity();
  // OpenCV 4.6's fitEllipseDirect is the preferred fit, but it tests its reduced scatter
  // matrix against an absolute determinant threshold in coordinates scaled by ~1/n, so for
  // more than ~150 points it silently returns cv::fitEllipse's unconstrained fit instead,
  // and for near-exact points its eigenvector is inaccurate (1e-3 of the size). Its two
  // siblings are tried as well and the candidate with the smallest RMS orthogonal distance
  // wins (the direct fit on ties).
  for (int method = first_method; method <= last_method; ++method) {
    rng.state = 0x6172656f6d6170ULL;  // fixed seed: "areomap"
    cv::RotatedRect box;
    try {
      box = method == 0   ? cv::fitEllipseDirect(scaled)
            : method == 1 ? cv::fitEllipseAMS(scaled)
                          : cv::fitEllipse(scaled);
    } catch (const cv::Exception&) {
      continue;
    }
    const std::optional<Ellipse> candidate = FromRotatedRect(box, mean, spread);
    if (!candidate.has_value()) continue;
    const double rms = RmsSampsonDistance(*candidate, finite);
    if (rms < best_rms) {
      best_rms = rms;
      best = candidate;
    }
  }
  rng.state = saved_state;
  return best;
}

}  // namespace

std::optional<Ellipse> FitEllipseDirect(const std::vector<Eigen::Vector2d>& points) {
  return FitEllipseOpenCv(points, 0, 2);
}

std::optional<Ellipse> FitEllipseFast(const std::vector<Eigen::Vector2d>& points) {
  // OpenCV 4.6's fitEllipseAMS tests its matrix against an absolute determinant threshold in
  // coordinates it scales by ~1/n: from ~160 points on (fewer on short arcs) it silently
  // returns the unconstrained cv::fitEllipse, which solves an n x 5 SVD (~7x AMS's cost, and
  // not constrained to an ellipse). AMS therefore sees at most kFastFitMaxPoints of the finite
  // points, evenly spread along their order.
  const std::vector<Eigen::Vector2d> finite = FinitePoints(points);
  const std::vector<Eigen::Vector2d>* used = &finite;
  std::vector<Eigen::Vector2d> spread;
  if (finite.size() > kFastFitMaxPoints) {
    const size_t stride = (finite.size() + kFastFitMaxPoints - 1) / kFastFitMaxPoints;
    spread.reserve(finite.size() / stride + 1);
    for (size_t i = 0; i < finite.size(); i += stride) spread.push_back(finite[i]);
    used = &spread;
  }
  if (std::optional<Ellipse> ams = FitEllipseOpenCv(*used, 1, 1)) return ams;
  return FitEllipseOpenCv(finite, 0, 2);
}

void GeometricFitOptions::Check() const {
  if (!(std::isfinite(loss_scale) && loss_scale > 0.0)) {
    throw Error("GeometricFitOptions.loss_scale must be a positive finite distance, got " +
                std::to_string(loss_scale));
  }
  if (max_num_iterations <= 0) {
    throw Error("GeometricFitOptions.max_num_iterations must be > 0, got " +
                std::to_string(max_num_iterations));
  }
  if (!(std::isfinite(function_tolerance) && function_tolerance > 0.0)) {
    throw Error("GeometricFitOptions.function_tolerance must be > 0, got " +
                std::to_string(function_tolerance));
  }
  if (!(std::isfinite(parameter_tolerance) && parameter_tolerance > 0.0)) {
    throw Error("GeometricFitOptions.parameter_tolerance must be > 0, got " +
                std::to_string(parameter_tolerance));
  }
  if (num_threads <= 0) {
    throw Error("GeometricFitOptions.num_threads must be > 0, got " + std::to_string(num_threads));
  }
}

std::string EllipseFitSummary::BriefReport() const {
  std::ostringstream out;
  out << std::setprecision(6) << "Ellipse fit: " << num_points << " points, "
      << (converged ? "converged" : "NOT converged") << " after " << num_iterations
      << " iterations; rms " << initial_rms_residual << " -> " << rms_residual << ", sigma0 "
      << sigma0 << "; center (" << ellipse.center.x() << ", " << ellipse.center.y() << ") +- ("
      << center_x_sigma << ", " << center_y_sigma << "), a " << ellipse.semi_major << " +- "
      << semi_major_sigma << ", b " << ellipse.semi_minor << " +- " << semi_minor_sigma
      << ", angle " << ellipse.angle << " +- " << angle_sigma << " rad";
  if (!converged && !message.empty()) out << " (" << message << ")";
  return out.str();
}

namespace {

// The summary before any fit: the initial ellipse, every statistic NaN.
EllipseFitSummary UnfittedSummary(const Ellipse& initial) {
  EllipseFitSummary summary;
  summary.ellipse = initial;
  summary.covariance.setConstant(kNaN);
  summary.initial_rms_residual = kNaN;
  summary.rms_residual = kNaN;
  summary.sigma0 = kNaN;
  summary.center_x_sigma = summary.center_y_sigma = kNaN;
  summary.semi_major_sigma = summary.semi_minor_sigma = summary.angle_sigma = kNaN;
  return summary;
}

// Ceres' solution of the orthogonal distance fit: the ellipse (normalized) and Ceres' summary.
struct GeometricSolution {
  Ellipse fitted;
  ceres::Solver::Summary ceres_summary;
};

// Minimises the orthogonal distances of `finite` to the ellipse from `initial`, with `loss`
// (null: least squares) applied inside the one residual block (OrthogonalDistancesCost).
GeometricSolution SolveOrthogonalDistances(const Ellipse& initial,
                                           const std::vector<Eigen::Vector2d>& finite,
                                           const ceres::LossFunction* loss,
                                           const GeometricFitOptions& options) {
  double shape[4] = {initial.center.x(), initial.center.y(), initial.semi_major,
                     initial.semi_minor};
  double angle[1] = {initial.angle};
  // The cost function outlives the problem (no ownership bookkeeping).
  OrthogonalDistancesCost cost(finite, loss);
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.disable_all_safety_checks = true;
  ceres::Problem problem(problem_options);
  problem.AddResidualBlock(&cost, nullptr, shape, angle);

  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = options.max_num_iterations;
  solver_options.function_tolerance = options.function_tolerance;
  solver_options.parameter_tolerance = options.parameter_tolerance;
  solver_options.num_threads = options.num_threads;
  solver_options.logging_type = ceres::SILENT;
  solver_options.minimizer_progress_to_stdout = false;
  GeometricSolution solution;
  ceres::Solve(solver_options, &problem, &solution.ceres_summary);

  Ellipse fitted;
  fitted.center = Eigen::Vector2d(shape[0], shape[1]);
  fitted.semi_major = shape[2];
  fitted.semi_minor = shape[3];
  fitted.angle = angle[0];
  solution.fitted = fitted.Normalized();
  return solution;
}

// The final rms residual and, when asked for and defined (dof > 0, a regular Jacobian), the
// covariance scaled by sigma0^2 and the sigmas, into `summary`.
void AddResidualAndCovariance(const Ellipse& fitted, const std::vector<Eigen::Vector2d>& finite,
                              const ceres::LossFunction* loss, const GeometricFitOptions& options,
                              double dof, EllipseFitSummary* summary) {
  // The covariance's Jacobian, at the normalized ellipse (the same curve as the parameter
  // blocks'), also gives the final distances.
  Eigen::Matrix<double, Eigen::Dynamic, 5> jacobian;
  Eigen::VectorXd residuals;
  const bool with_jacobian = options.compute_covariance && dof > 0.0 &&
                             DistanceJacobian(fitted, finite, &jacobian, &residuals);
  summary->rms_residual = with_jacobian ? RootMeanSquare(residuals) : RmsDistance(fitted, finite);
  Eigen::Matrix<double, 5, 5> covariance;
  if (!with_jacobian || !ComputeCovariance(jacobian, residuals, loss, &covariance)) return;
  summary->covariance = covariance * (summary->sigma0 * summary->sigma0);
  if (std::isinf(covariance(4, 4))) summary->covariance(4, 4) = kInf;  // even when sigma0 = 0
  summary->covariance_valid = true;
  summary->center_x_sigma = std::sqrt(summary->covariance(0, 0));
  summary->center_y_sigma = std::sqrt(summary->covariance(1, 1));
  summary->semi_major_sigma = std::sqrt(summary->covariance(2, 2));
  summary->semi_minor_sigma = std::sqrt(summary->covariance(3, 3));
  summary->angle_sigma = std::sqrt(summary->covariance(4, 4));
}

}  // namespace

EllipseFitSummary RefineEllipseGeometric(const Ellipse& initial,
                                         const std::vector<Eigen::Vector2d>& points,
                                         const GeometricFitOptions& options) {
  options.Check();
  EllipseFitSummary summary = UnfittedSummary(initial);
  const std::vector<Eigen::Vector2d> finite = FinitePoints(points);
  summary.num_points = static_cast<int>(finite.size());
  if (!initial.HasPositiveAxes()) {
    summary.message = "initial ellipse needs finite fields and positive axes";
    return summary;
  }
  summary.initial_rms_residual = RmsDistance(initial, finite);
  if (finite.size() < 5) {
    summary.message = "need at least 5 finite points, got " + std::to_string(finite.size());
    return summary;
  }
  // The loss outlives the solve: the covariance below weights the distances with it.
  const std::unique_ptr<ceres::LossFunction> loss(MakeLoss(options));
  const GeometricSolution solution = SolveOrthogonalDistances(initial, finite, loss.get(), options);
  const Ellipse& fitted = solution.fitted;
  const ceres::Solver::Summary& ceres_summary = solution.ceres_summary;
  summary.num_iterations = static_cast<int>(ceres_summary.iterations.size()) - 1;
  summary.message = ceres_summary.message;
  if (!fitted.IsValid()) {
    summary.message = "fit diverged to an invalid ellipse (" + ceres_summary.message + ")";
    return summary;
  }
  summary.ellipse = fitted;
  summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;
  const double dof = static_cast<double>(finite.size()) - 5.0;
  if (dof > 0.0) summary.sigma0 = std::sqrt(2.0 * ceres_summary.final_cost / dof);
  AddResidualAndCovariance(fitted, finite, loss.get(), options, dof, &summary);
  return summary;
}

double EllipseFitSimilarity(const Ellipse& e, const std::vector<Eigen::Vector2d>& points) {
  if (points.empty() || !e.HasPositiveAxes()) return kNaN;
  double sum = 0.0;
  for (const Eigen::Vector2d& p : points) sum += (p - e.center).norm();
  return sum / static_cast<double>(points.size()) / e.MeanRadius();
}

double EdgeCoverage(const Ellipse& e, const std::vector<Eigen::Vector2d>& points,
                    double max_distance, int bins) {
  if (bins < 1) throw Error("EdgeCoverage: bins must be >= 1, got " + std::to_string(bins));
  if (!(std::isfinite(max_distance) && max_distance >= 0.0)) {
    throw Error("EdgeCoverage: max_distance must be a finite distance >= 0, got " +
                std::to_string(max_distance));
  }
  if (!e.HasPositiveAxes()) return 0.0;
  std::vector<bool> hit(static_cast<size_t>(bins), false);
  for (const Eigen::Vector2d& p : points) {
    if (!p.allFinite() || !(std::abs(e.SignedDistance(p)) <= max_distance)) continue;
    const double t = e.ClosestParameter(p);  // [0, 2 pi)
    const int bin = std::clamp(static_cast<int>(t / (2.0 * std::numbers::pi) * bins), 0, bins - 1);
    hit[static_cast<size_t>(bin)] = true;
  }
  return static_cast<double>(std::count(hit.begin(), hit.end(), true)) / bins;
}

}  // namespace areomap
