// Least-squares fitting of the rock models (ch. 2.3.2) with Ceres.
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Dense>

#include "areomap/landmarks/rock_model.h"
#include "areomap/map/error.h"
#include "rock_model_frame.h"

namespace areomap {

namespace {

using namespace rock_model_internal;

struct SurfaceResidual {
  SurfaceResidual(RockModelShape s, const Eigen::Vector3d& point) : shape(s), p(point) {}
  template <typename T>
  bool operator()(const T* q, T* residual) const {
    T m[3];
    ToModelFrame(q, T(p.x()), T(p.y()), T(p.z()), m);
    residual[0] = SurfaceDistance(shape, m[0], m[1], m[2], q[kHeight], q[kA], q[kB]);
    return true;
  }
  RockModelShape shape;
  Eigen::Vector3d p;
};

bool UsesB(RockModelShape s) { return s == RockModelShape::kSemiEllipsoid; }
bool UsesPhi(RockModelShape s) {
  return s == RockModelShape::kSemiEllipsoid || s == RockModelShape::kTetrahedron;
}

// Solves one start; returns the final cost (infinite on failure) and the free indices.
double Solve(const std::vector<Eigen::Vector3d>& points, RockModelShape shape,
             const RockModelFitOptions& options, double* q, std::vector<int>* free_indices,
             Eigen::MatrixXd* jacobian) {
  ceres::Problem problem;
  for (const Eigen::Vector3d& p : points) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SurfaceResidual, 1, kCount>(new SurfaceResidual(shape, p)),
        nullptr, q);
  }
  std::vector<int> constant;
  free_indices->clear();
  for (int i = 0; i < kCount; ++i) {
    const bool is_free = i == kHeight || i == kA || (i == kB && UsesB(shape)) ||
                         (i == kPhi && UsesPhi(shape)) ||
                         ((i == kAlpha || i == kBeta) && options.complex_model) ||
                         ((i == kCenterX || i == kCenterY) && options.estimate_center);
    (is_free ? *free_indices : constant).push_back(i);
  }
  problem.SetManifold(q, new ceres::SubsetManifold(kCount, constant));
  for (int i : {kHeight, kA, kB}) {
    problem.SetParameterLowerBound(q, i, options.min_size_m);
    problem.SetParameterUpperBound(q, i,
                                   i == kHeight ? options.max_height_m : options.max_radius_m);
  }
  if (options.estimate_center) {
    for (int i : {kCenterX, kCenterY}) {
      problem.SetParameterLowerBound(q, i, q[i] - options.max_center_offset_m);
      problem.SetParameterUpperBound(q, i, q[i] + options.max_center_offset_m);
    }
  }
  if (options.complex_model) {
    for (int i : {kAlpha, kBeta}) {
      problem.SetParameterLowerBound(q, i, -options.max_tilt_rad);
      problem.SetParameterUpperBound(q, i, options.max_tilt_rad);
    }
  }
  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_QR;
  solver.max_num_iterations = options.max_num_iterations;
  solver.function_tolerance = 1e-14;
  solver.gradient_tolerance = 1e-14;
  solver.parameter_tolerance = 1e-12;
  solver.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);
  if (!summary.IsSolutionUsable()) return std::numeric_limits<double>::infinity();
  ceres::CRSMatrix crs;
  double cost = 0.0;
  problem.Evaluate(ceres::Problem::EvaluateOptions(), &cost, nullptr, nullptr, &crs);
  jacobian->setZero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int k = crs.rows[r]; k < crs.rows[r + 1]; ++k) (*jacobian)(r, crs.cols[k]) = crs.values[k];
  }
  return summary.final_cost;
}

double WrapAngle(double angle, double period) {
  angle = std::fmod(angle, period);
  return angle < 0.0 ? angle + period : angle;
}

// The best of the starts: its final cost (infinite when every start failed), parameters, free
// parameter indices and Jacobian.
struct BestStart {
  double cost = std::numeric_limits<double>::infinity();
  double q[kCount] = {};
  std::vector<int> free_indices;
  Eigen::MatrixXd jacobian;
};

// Solves from every start and keeps the lowest cost. Start: the given centre; height from the
// highest point, radius from the widest point.
BestStart SolveFromStarts(const std::vector<Eigen::Vector3d>& points_in_rock, RockModelShape shape,
                          const RockModelFitOptions& options, const RockModelParameters& start) {
  double top = 0.0, reach = 0.0;
  for (const Eigen::Vector3d& p : points_in_rock) {
    top = std::max(top, p.z());
    reach = std::max(reach, std::hypot(p.x() - start.center_x, p.y() - start.center_y));
  }
  const auto inside = [&](double value, double upper) {
    return std::clamp(value, 1.01 * options.min_size_m, 0.99 * upper);
  };
  const double h0 =
      inside(start.height > 0.0 ? start.height : std::max(top, 1e-2), options.max_height_m);
  const double a0 = inside(start.a > 0.0 ? start.a : std::max(reach, 1e-2), options.max_radius_m);
  // Starts for the azimuth of the anisotropic shapes (their cost has several basins).
  std::vector<double> phi_starts = {start.phi};
  // (An ellipse's azimuth has period pi and a/b swap at pi/2; a triangle's period is 2 pi/3.)
  if (shape == RockModelShape::kSemiEllipsoid) phi_starts = {0.0, std::numbers::pi / 4.0};
  if (shape == RockModelShape::kTetrahedron) phi_starts = {0.0, std::numbers::pi / 3.0};
  BestStart best;
  for (double phi : phi_starts) {
    double q[kCount] = {h0,
                        a0,
                        UsesB(shape) ? 0.8 * a0 : a0,
                        phi,
                        options.complex_model ? start.alpha : 0.0,
                        options.complex_model ? start.beta : 0.0,
                        start.center_x,
                        start.center_y};
    std::vector<int> indices;
    Eigen::MatrixXd j;
    const double cost = Solve(points_in_rock, shape, options, q, &indices, &j);
    if (cost < best.cost) {
      best.cost = cost;
      std::copy(q, q + kCount, best.q);
      best.free_indices = indices;
      best.jacobian = j;
    }
  }
  return best;
}

// The fitted parameters of `shape` (b = a and phi = 0 where the shape has none).
void SetParameters(const BestStart& best, RockModelShape shape, RockModelParameters* m) {
  m->height = best.q[kHeight];
  m->a = best.q[kA];
  m->b = UsesB(shape) ? best.q[kB] : best.q[kA];
  m->phi = UsesPhi(shape) ? best.q[kPhi] : 0.0;
  m->alpha = best.q[kAlpha];
  m->beta = best.q[kBeta];
  m->center_x = best.q[kCenterX];
  m->center_y = best.q[kCenterY];
}

// 1-sigma: (J^T J)^-1 scaled by the residual variance (redundancy n - u); NaN where J^T J is
// singular, 0 where nothing is left over.
void SetSigmas(const BestStart& best, RockModelShape shape, RockModelFit* fit) {
  const int unknowns = static_cast<int>(best.free_indices.size());
  const int redundancy = fit->point_count - unknowns;
  if (redundancy > 0 && best.jacobian.cols() == unknowns) {
    const Eigen::MatrixXd normal = best.jacobian.transpose() * best.jacobian;
    Eigen::LDLT<Eigen::MatrixXd> ldlt(normal);
    if (ldlt.info() == Eigen::Success && ldlt.rcond() > 1e-14) {
      const Eigen::MatrixXd cov = ldlt.solve(Eigen::MatrixXd::Identity(unknowns, unknowns)) *
                                  (2.0 * best.cost / redundancy);
      for (int k = 0; k < unknowns; ++k) {
        fit->sigma[best.free_indices[k]] = std::sqrt(std::max(cov(k, k), 0.0));
      }
    } else {
      fit->sigma.fill(std::nan(""));
    }
  }
  if (!UsesB(shape)) fit->sigma[kB] = fit->sigma[kA];
}

// Canonical form: a >= b for the semi-ellipsoid; azimuths in their period.
void Canonicalize(RockModelShape shape, RockModelFit* fit) {
  RockModelParameters& m = fit->parameters;
  if (shape == RockModelShape::kSemiEllipsoid) {
    if (m.b > m.a) {
      std::swap(m.a, m.b);
      std::swap(fit->sigma[kA], fit->sigma[kB]);
      m.phi += std::numbers::pi / 2.0;
    }
    m.phi = WrapAngle(m.phi, std::numbers::pi);
  } else if (shape == RockModelShape::kTetrahedron) {
    m.phi = WrapAngle(m.phi, 2.0 * std::numbers::pi / 3.0);
  }
}

// Eq. 2.13: the RMS of the points' vertical distances from the model's surface [m].
double VerticalRms(const std::vector<Eigen::Vector3d>& points_in_rock,
                   const RockModelParameters& m) {
  double sum = 0.0;
  for (const Eigen::Vector3d& p : points_in_rock) {
    const double dz = p.z() - m.SurfaceZ(p.x(), p.y(), p.z());
    sum += dz * dz;
  }
  return std::sqrt(sum / static_cast<double>(points_in_rock.size()));
}

}  // namespace

void RockModelFitOptions::Check() const {
  RequireOption(min_points >= 3, "RockModelFitOptions.min_points", ">= 3");
  RequireOption(max_num_iterations > 0, "RockModelFitOptions.max_num_iterations", "> 0");
  RequireOption(max_tilt_rad > 0.0 && max_tilt_rad < std::numbers::pi / 2.0,
                "RockModelFitOptions.max_tilt_rad", "between 0 and pi/2");
  RequireOption(min_size_m > 0.0 && max_height_m > min_size_m && max_radius_m > min_size_m,
                "RockModelFitOptions.min_size_m", "0 < min_size_m < max_height_m, max_radius_m");
  RequireOption(max_center_offset_m > 0.0, "RockModelFitOptions.max_center_offset_m", "> 0 m");
}

RockModelFit FitRockModel(const std::vector<Eigen::Vector3d>& points_in_rock, RockModelShape shape,
                          const RockModelFitOptions& options,
                          const std::optional<RockModelParameters>& initial) {
  options.Check();
  RockModelFit fit;
  fit.complex_model = options.complex_model;
  fit.parameters.shape = shape;
  fit.point_count = static_cast<int>(points_in_rock.size());
  fit.sigma.fill(0.0);
  if (fit.point_count < options.min_points) {
    fit.message = "too few surface points (" + std::to_string(fit.point_count) + " < " +
                  std::to_string(options.min_points) + ")";
    return fit;
  }
  const BestStart best =
      SolveFromStarts(points_in_rock, shape, options, initial.value_or(RockModelParameters{}));
  if (!std::isfinite(best.cost)) {
    fit.message = "solver failed";
    return fit;
  }
  SetParameters(best, shape, &fit.parameters);
  fit.geometric_rms_m = std::sqrt(2.0 * best.cost / fit.point_count);
  SetSigmas(best, shape, &fit);
  Canonicalize(shape, &fit);
  const RockModelParameters& m = fit.parameters;
  fit.rms_m = VerticalRms(points_in_rock, m);
  const bool at_bound =
      m.height < 2e-3 || m.a < 2e-3 || m.b < 2e-3 || m.height > 19.0 || m.a > 19.0;
  if (at_bound) {
    fit.message = "degenerate fit (a size parameter reached its bound)";
    return fit;
  }
  fit.converged = true;
  return fit;
}

std::vector<RockModelFit> FitAllRockModels(const std::vector<Eigen::Vector3d>& points_in_rock,
                                           const RockModelFitOptions& options,
                                           const std::optional<RockModelParameters>& initial) {
  std::vector<RockModelFit> fits;
  for (RockModelShape shape : kAllRockModelShapes) {
    fits.push_back(FitRockModel(points_in_rock, shape, options, initial));
  }
  std::stable_sort(fits.begin(), fits.end(), [](const RockModelFit& x, const RockModelFit& y) {
    if (x.converged != y.converged) return x.converged;
    return x.rms_m < y.rms_m;
  });
  return fits;
}

}  // namespace areomap
