// Localization error analysis (ch. 4.1): eq. 4.2 covariance, Gauss-Helmert conformal transform
// (eqs. 4.4-4.6), adjacent-site error and RE (eqs. 4.7-4.9), the configuration study
// (Figs. 4.1-4.5).
#include "areomap/landmarks/localization_error.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <ceres/ceres.h>
#include <Eigen/Dense>
#include <boost/math/distributions/chi_squared.hpp>

#include "areomap/map/error.h"

namespace areomap {

namespace {

Eigen::Matrix<double, 2, 4> DesignB(const Eigen::Vector2d& p) {
  Eigen::Matrix<double, 2, 4> e;
  e << p.x(), -p.y(), 1.0, 0.0, p.y(), p.x(), 0.0, 1.0;
  return e;
}

// Unweighted linear solution of eq. 4.4: the start of the adjustment.
std::optional<Eigen::Vector4d> LinearConformal(const std::vector<PlanarTiePoint>& ties) {
  Eigen::MatrixXd design(2 * ties.size(), 4);
  Eigen::VectorXd rhs(2 * ties.size());
  for (size_t i = 0; i < ties.size(); ++i) {
    design.block<2, 4>(2 * i, 0) = DesignB(ties[i].in_adjacent);
    rhs.segment<2>(2 * i) = ties[i].in_current;
  }
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(design);
  if (qr.rank() < 4) return std::nullopt;
  return Eigen::Vector4d(qr.solve(rhs));
}

// d f / d (x1, y1, x2, y2) of eq. 4.4's condition f = current - T(adjacent) at parameters x.
Eigen::Matrix<double, 2, 4> ConditionJacobian(const Eigen::Vector4d& x) {
  Eigen::Matrix<double, 2, 4> a;
  a << 1, 0, -x(0), x(1), 0, 1, -x(1), -x(0);
  return a;
}

// One tie point's condition whitened by its covariance, as a function of the parameters alone.
// The condition f = current - T(adjacent) is linear in the observations, so the corrections that
// satisfy it with the least v^T Sigma^-1 v leave chi2 = f^T (A Sigma A^T)^-1 f: the residual is
// L^-1 f with L L^T = A Sigma A^T = Sigma_current + R Sigma_adjacent R^T, R = [[a, -b], [b, a]].
struct EliminatedCondition {
  Eigen::Vector2d current, adjacent;
  Eigen::Matrix2d sigma_current, sigma_adjacent;

  template <typename T>
  bool operator()(const T* x, T* residual) const {
    const T f0 = T(current.x()) - (x[0] * adjacent.x() - x[1] * adjacent.y() + x[2]);
    const T f1 = T(current.y()) - (x[1] * adjacent.x() + x[0] * adjacent.y() + x[3]);
    Eigen::Matrix<T, 2, 2> r;
    r << x[0], -x[1], x[1], x[0];
    const Eigen::Matrix<T, 2, 2> m =
        sigma_current.cast<T>() + r * sigma_adjacent.cast<T>() * r.transpose();
    using std::sqrt;
    const T l00 = sqrt(m(0, 0));
    const T l10 = m(1, 0) / l00;
    const T l11 = sqrt(m(1, 1) - l10 * l10);
    residual[0] = f0 / l00;
    residual[1] = (f1 - l10 * residual[0]) / l11;
    return true;
  }
};

// The parameters minimising the eliminated chi-square (Levenberg-Marquardt from `start`), the
// Gauss-Helmert solution of eq. 4.4; nullopt unless the solver converged. (The Gauss-Helmert
// iteration's own full steps, used before, converged linearly with a tie point tens of sigmas
// off and cycled between two points with one metres off, never ending.)
std::optional<Eigen::Vector4d> MinimumChi2Parameters(const std::vector<PlanarTiePoint>& ties,
                                                     const Eigen::Vector4d& start,
                                                     int* iterations) {
  Eigen::Vector4d x = start;
  ceres::Problem problem;
  for (const PlanarTiePoint& t : ties) {
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<EliminatedCondition, 2, 4>(new EliminatedCondition{
            t.in_current, t.in_adjacent, t.covariance_current, t.covariance_adjacent}),
        nullptr, x.data());
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 200;
  options.function_tolerance = 1e-14;
  options.gradient_tolerance = 1e-16;
  options.parameter_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  *iterations = static_cast<int>(summary.iterations.size());
  if (summary.termination_type != ceres::CONVERGENCE || !x.allFinite()) return std::nullopt;
  return x;
}

}  // namespace

Eigen::Matrix2d PolarPositionCovariance(double range_m, double azimuth_rad, double sigma_range_m,
                                        double sigma_azimuth_rad) {
  const double c = std::cos(azimuth_rad), s = std::sin(azimuth_rad);
  const double sr2 = sigma_range_m * sigma_range_m;
  const double st2 = range_m * range_m * sigma_azimuth_rad * sigma_azimuth_rad;
  Eigen::Matrix2d cov;
  cov(0, 0) = c * c * sr2 + s * s * st2;
  cov(1, 1) = s * s * sr2 + c * c * st2;
  cov(0, 1) = cov(1, 0) = s * c * sr2 - s * c * st2;
  return cov;
}

void LocalizationCamera::Check() const {
  RequireOption(baseline_m > 0.0, "LocalizationCamera.baseline_m", "> 0 m");
  RequireOption(focal_px > 10.0, "LocalizationCamera.focal_px", "> 10 px");
  RequireOption(parallax_sigma_px > 0.0, "LocalizationCamera.parallax_sigma_px", "> 0 px");
  RequireOption(azimuth_sigma_px >= 0.0, "LocalizationCamera.azimuth_sigma_px", ">= 0 px");
}

Eigen::Matrix2d LocalizationCamera::Covariance(const Eigen::Vector2d& point,
                                               const Eigen::Vector2d& site) const {
  const Eigen::Vector2d d = point - site;
  const double range = d.norm();
  const double sigma_range = range * range * parallax_sigma_px / (baseline_m * focal_px);  // 4.3
  return PolarPositionCovariance(range, std::atan2(d.y(), d.x()), sigma_range,
                                 azimuth_sigma_px / focal_px);
}

Eigen::Vector2d ConformalTransform2d::Apply(const Eigen::Vector2d& in_adjacent) const {
  return DesignB(in_adjacent) * parameters;
}

Eigen::Matrix2d ConformalTransform2d::PointCovariance(const Eigen::Vector2d& in_adjacent) const {
  const Eigen::Matrix<double, 2, 4> e = DesignB(in_adjacent);
  return e * covariance * e.transpose();
}

std::optional<ConformalTransform2d> FitConformalTransform(const std::vector<PlanarTiePoint>& ties) {
  if (ties.size() < 2) return std::nullopt;
  const std::optional<Eigen::Vector4d> start = LinearConformal(ties);
  if (!start) return std::nullopt;
  ConformalTransform2d result;
  const std::optional<Eigen::Vector4d> x = MinimumChi2Parameters(ties, *start, &result.iterations);
  if (!x) return std::nullopt;
  // The Gauss-Helmert model's normal matrix (eq. 4.6) at the solution: the condition's
  // derivative by the parameters at the corrected adjacent points.
  const Eigen::Matrix<double, 2, 4> a = ConditionJacobian(*x);
  Eigen::Matrix4d normal = Eigen::Matrix4d::Zero();
  for (const PlanarTiePoint& t : ties) {
    Eigen::Matrix4d sigma = Eigen::Matrix4d::Zero();
    sigma.topLeftCorner<2, 2>() = t.covariance_current;
    sigma.bottomRightCorner<2, 2>() = t.covariance_adjacent;
    const Eigen::Matrix2d m = a * sigma * a.transpose();
    if (!(std::abs(m.determinant()) >= 1e-300)) return std::nullopt;
    const Eigen::Matrix2d m_inv = m.inverse();
    const Eigen::Vector2d f = t.in_current - DesignB(t.in_adjacent) * *x;
    const Eigen::Vector4d v = -sigma * a.transpose() * m_inv * f;  // The least corrections.
    const Eigen::Matrix<double, 2, 4> b = -DesignB(t.in_adjacent + v.tail<2>());
    normal += b.transpose() * m_inv * b;
    result.chi2 += f.dot(m_inv * f);
  }
  const Eigen::FullPivLU<Eigen::Matrix4d> lu(normal);
  if (!lu.isInvertible()) return std::nullopt;
  result.parameters = *x;
  result.covariance = lu.inverse();  // Eq. 4.6.
  result.redundancy = static_cast<int>(2 * ties.size()) - 4;
  return result;
}

std::vector<double> LeaveOneOutChi2(const std::vector<PlanarTiePoint>& ties) {
  std::vector<double> chi2(ties.size(), std::nan(""));
  std::vector<PlanarTiePoint> others;
  for (size_t k = 0; k < ties.size(); ++k) {
    others.clear();
    for (size_t i = 0; i < ties.size(); ++i) {
      if (i != k) others.push_back(ties[i]);
    }
    const std::optional<ConformalTransform2d> fit = FitConformalTransform(others);
    if (!fit) continue;
    const PlanarTiePoint& t = ties[k];
    const Eigen::Vector4d& p = fit->parameters;
    Eigen::Matrix2d scaled_rotation;
    scaled_rotation << p(0), -p(1), p(1), p(0);
    const Eigen::Vector2d discrepancy = t.in_current - fit->Apply(t.in_adjacent);
    const Eigen::Matrix2d covariance =
        t.covariance_current +
        scaled_rotation * t.covariance_adjacent * scaled_rotation.transpose() +
        fit->PointCovariance(t.in_adjacent);
    chi2[k] = discrepancy.dot(covariance.ldlt().solve(discrepancy));
  }
  return chi2;
}

double ConvergenceAngle(const Eigen::Vector2d& site, const std::vector<Eigen::Vector2d>& points) {
  std::vector<double> azimuths;
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d d = p - site;
    if (d.norm() > 0.0) azimuths.push_back(std::atan2(d.y(), d.x()));
  }
  if (azimuths.size() < 2) return 0.0;
  std::sort(azimuths.begin(), azimuths.end());
  double largest_gap = azimuths.front() + 2.0 * std::numbers::pi - azimuths.back();
  for (size_t i = 1; i < azimuths.size(); ++i) {
    largest_gap = std::max(largest_gap, azimuths[i] - azimuths[i - 1]);
  }
  return 2.0 * std::numbers::pi - largest_gap;
}

double DistanceRatio(const Eigen::Vector3d& point, const Eigen::Vector3d& site_a,
                     const Eigen::Vector3d& site_b) {
  const double d1 = (point - site_a).norm(), d2 = (point - site_b).norm();
  const double far = std::max(d1, d2);
  return far > 0.0 ? std::min(d1, d2) / far : 0.0;
}

PooledVarianceFactor PoolVarianceFactor(const std::vector<SitePairError>& fits) {
  PooledVarianceFactor pooled;
  for (const SitePairError& f : fits) {
    if (f.redundancy <= 0) continue;
    ++pooled.fits;
    pooled.chi2 += f.chi2;
    pooled.redundancy += f.redundancy;
  }
  if (pooled.redundancy == 0) {
    pooled.estimate = pooled.upper_95 = std::nan("");
    return pooled;
  }
  const double r = static_cast<double>(pooled.redundancy);
  pooled.estimate = pooled.chi2 / r;
  pooled.upper_95 = pooled.chi2 / boost::math::quantile(boost::math::chi_squared(r), 0.05);
  return pooled;
}

std::optional<SitePairError> EvaluateSitePair(const std::vector<PlanarTiePoint>& ties,
                                              const Eigen::Vector2d& adjacent_in_current) {
  const std::optional<ConformalTransform2d> transform = FitConformalTransform(ties);
  if (!transform) return std::nullopt;
  SitePairError e;
  e.traverse_length_m = adjacent_in_current.norm();
  e.chi2 = transform->chi2;
  e.redundancy = transform->redundancy;
  e.position_sigma_m = std::sqrt(transform->PointCovariance(Eigen::Vector2d::Zero()).trace());
  e.relative_error_percent =
      e.traverse_length_m > 0.0 ? 100.0 * e.position_sigma_m / e.traverse_length_m : 0.0;
  std::vector<Eigen::Vector2d> in_current;
  for (const PlanarTiePoint& t : ties) {
    in_current.push_back(t.in_current);
    e.mean_distance_ratio +=
        DistanceRatio(Eigen::Vector3d(t.in_current.x(), t.in_current.y(), 0.0),
                      Eigen::Vector3d::Zero(),
                      Eigen::Vector3d(adjacent_in_current.x(), adjacent_in_current.y(), 0.0)) /
        static_cast<double>(ties.size());
  }
  e.convergence_current_rad = ConvergenceAngle(Eigen::Vector2d::Zero(), in_current);
  e.convergence_adjacent_rad = ConvergenceAngle(adjacent_in_current, in_current);
  return e;
}

void ConfigurationStudyOptions::Check() const {
  RequireOption(!landmark_counts.empty(), "ConfigurationStudyOptions.landmark_counts",
                "at least one of 2, 3, 4, 6, 9");
  for (int count : landmark_counts) {
    RequireOption(count == 2 || count == 3 || count == 4 || count == 6 || count == 9,
                  "ConfigurationStudyOptions.landmark_counts", "values among 2, 3, 4, 6, 9");
  }
  RequireOption(!traverse_lengths_m.empty(), "ConfigurationStudyOptions.traverse_lengths_m",
                "at least one length");
  for (double d : traverse_lengths_m) {
    RequireOption(d > 0.0 && d <= 1000.0, "ConfigurationStudyOptions.traverse_lengths_m",
                  "lengths in (0, 1000] m");
  }
  RequireOption(min_convergence_deg > 0.0 && max_convergence_deg < 180.0 &&
                    min_convergence_deg <= max_convergence_deg,
                "ConfigurationStudyOptions.min_convergence_deg",
                "0 < min <= max_convergence_deg < 180");
  // A step of 1e-9 degrees once ran for ever: at most 18 000 angles per curve.
  RequireOption(convergence_step_deg >= 0.01, "ConfigurationStudyOptions.convergence_step_deg",
                ">= 0.01 degrees");
  camera.Check();
}

std::vector<Eigen::Vector2d> StudyLandmarks(int landmark_count, double traverse_length_m,
                                            double convergence_deg) {
  // Unit figures centred on the origin, symmetric under x -> -x so both sites see the same
  // convergence angle (Fig. 4.1).
  std::vector<Eigen::Vector2d> unit;
  switch (landmark_count) {
    case 2:
      unit = {{0, 1}, {0, -1}};
      break;
    case 3:
      for (int k = 0; k < 3; ++k) {
        const double t = std::numbers::pi / 2.0 + 2.0 * std::numbers::pi / 3.0 * k;
        unit.emplace_back(std::cos(t), std::sin(t));
      }
      break;
    case 4:
      unit = {{1, 1}, {-1, 1}, {-1, -1}, {1, -1}};
      break;
    case 6:
      for (int k = 0; k < 6; ++k)
        unit.emplace_back(std::cos(std::numbers::pi / 3.0 * k),
                          std::sin(std::numbers::pi / 3.0 * k));
      break;
    case 9:
      for (int i = -1; i <= 1; ++i) {
        for (int j = -1; j <= 1; ++j) unit.emplace_back(i, j);
      }
      break;
    default:
      throw Error("landmark count " + std::to_string(landmark_count) +
                  " is not part of the study: expected 2, 3, 4, 6 or 9");
  }
  RequireOption(convergence_deg > 0.0 && convergence_deg < 180.0, "convergence_deg",
                "between 0 and 180 degrees");
  RequireOption(traverse_length_m > 0.0, "traverse_length_m", "> 0 m");
  const double target = convergence_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d middle(0.5 * traverse_length_m, 0.0);
  const auto place = [&](double size) {
    std::vector<Eigen::Vector2d> points;
    for (const Eigen::Vector2d& u : unit) points.push_back(middle + size * u);
    return points;
  };
  const auto angle = [&](double size) { return ConvergenceAngle({0, 0}, place(size)); };
  // The angle grows with the size until a landmark reaches the site's abscissa; bracket, bisect.
  double lo = 0.0, hi = 1e-3 * traverse_length_m;
  while (angle(hi) < target && hi < 1e4 * traverse_length_m) {
    lo = hi;
    hi *= 2.0;
  }
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (angle(mid) < target ? lo : hi) = mid;
  }
  return place(0.5 * (lo + hi));
}

ConfigurationSample EvaluateConfiguration(int landmark_count, double traverse_length_m,
                                          double convergence_deg,
                                          const LocalizationCamera& camera) {
  camera.Check();
  const std::vector<Eigen::Vector2d> landmarks =
      StudyLandmarks(landmark_count, traverse_length_m, convergence_deg);
  const Eigen::Vector2d adjacent(traverse_length_m, 0.0);
  std::vector<PlanarTiePoint> ties;
  for (const Eigen::Vector2d& p : landmarks) {
    PlanarTiePoint t;
    t.in_current = p;
    t.covariance_current = camera.Covariance(p, Eigen::Vector2d::Zero());
    t.in_adjacent = p - adjacent;  // Both frames share their axes in the study.
    t.covariance_adjacent = camera.Covariance(p, adjacent);
    ties.push_back(t);
  }
  ConfigurationSample sample;
  sample.landmark_count = landmark_count;
  sample.traverse_length_m = traverse_length_m;
  sample.convergence_deg = convergence_deg;
  const Eigen::Vector2d middle(0.5 * traverse_length_m, 0.0);
  for (const Eigen::Vector2d& p : landmarks) {
    sample.figure_size_m = std::max(sample.figure_size_m, (p - middle).norm());
  }
  const std::optional<SitePairError> error = EvaluateSitePair(ties, adjacent);
  if (!error) {
    sample.position_sigma_m = sample.relative_error_percent = std::nan("");
    return sample;
  }
  sample.position_sigma_m = error->position_sigma_m;
  sample.relative_error_percent = error->relative_error_percent;
  return sample;
}

std::vector<ConfigurationSample> RunConfigurationStudy(const ConfigurationStudyOptions& options) {
  options.Check();
  std::vector<ConfigurationSample> samples;
  for (double length : options.traverse_lengths_m) {
    for (int count : options.landmark_counts) {
      for (double angle = options.min_convergence_deg; angle <= options.max_convergence_deg + 1e-9;
           angle += options.convergence_step_deg) {
        samples.push_back(EvaluateConfiguration(count, length, angle, options.camera));
      }
    }
  }
  return samples;
}

}  // namespace areomap
