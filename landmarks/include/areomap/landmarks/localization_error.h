// Rover localization error analysis across two sites (ch. 4.1, eqs. 4.1-4.9).
//
// Frames: 2D horizontal site frames, x north, y east [m] (the MER site frame without z); each
// site's own frame has its origin at that site. Angles in radians, azimuth clockwise from north
// (x toward y). Covariances in m^2.
//
// The adjacent site is tied to the current one by a 2D conformal (Helmert) transformation
// estimated from tie points measured at both sites (eq. 4.4), solved as a general
// (Gauss-Helmert) least-squares model because both sets of coordinates have errors (eq. 4.5);
// the transformation covariance (eq. 4.6) is propagated to the adjacent site's position
// (eqs. 4.7, 4.8) and divided by the traverse length (RE, eq. 4.9).
//
// Failures: a transformation that cannot be estimated (fewer than 2 tie points, coincident
// points, no convergence) is std::nullopt; invalid options throw areomap::Error.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace areomap {

// Eq. 4.2: covariance of (X, Y) = r (cos theta, sin theta) (eq. 4.1) from sigma_r and sigma_theta.
Eigen::Matrix2d PolarPositionCovariance(double range_m, double azimuth_rad, double sigma_range_m,
                                        double sigma_azimuth_rad);

// Camera parameters of the error model: eq. 4.3 for sigma_r, one pixel for sigma_theta (ch. 4.1).
// Table 1.1 also lists 0.76 mrad/px for the Navcam; 1 / 1222.5 px = 0.82 mrad is what 14.67 mm
// on 12 um pixels gives, and it reproduces Figs. 4.2-4.5 (0.76 mrad gives REs ~7 % lower).
struct LocalizationCamera {
  double baseline_m = 0.20;        // Navcam stereo base (Table 1.1).
  double focal_px = 1222.5;        // Navcam: 14.67 mm on 12 um pixels (Table 1.1).
  double parallax_sigma_px = 0.5;  // sigma_p of eq. 4.3.
  double azimuth_sigma_px = 1.0;   // sigma_theta in pixels (ch. 4.1: about one pixel).
  void Check() const;              // Throws areomap::Error naming the field.
  // Eq. 4.2 covariance of a landmark at `point` seen from `site` (same 2D frame).
  Eigen::Matrix2d Covariance(const Eigen::Vector2d& point, const Eigen::Vector2d& site) const;
};

// One tie point: the landmark measured in both site frames, with covariances.
struct PlanarTiePoint {
  Eigen::Vector2d in_current = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance_current = Eigen::Matrix2d::Identity();
  Eigen::Vector2d in_adjacent = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance_adjacent = Eigen::Matrix2d::Identity();
};

// current = [a -b; b a] adjacent + (c, d) (eq. 4.4): scale s = |(a, b)|, rotation atan2(b, a).
struct ConformalTransform2d {
  Eigen::Vector4d parameters = Eigen::Vector4d(1, 0, 0, 0);  // (a, b, c, d).
  Eigen::Matrix4d covariance = Eigen::Matrix4d::Zero();      // Eq. 4.6 [m^2 for c, d].
  int iterations = 0;                                        // The solver's.
  double chi2 = 0.0;   // v^T Sigma^-1 v of the adjusted observations.
  int redundancy = 0;  // 2 n - 4.

  Eigen::Vector2d Apply(const Eigen::Vector2d& in_adjacent) const;
  // Eqs. 4.7, 4.8: covariance of a point of the adjacent frame mapped to the current frame.
  Eigen::Matrix2d PointCovariance(const Eigen::Vector2d& in_adjacent) const;
};

// Gauss-Helmert adjustment of eq. 4.4 with errors in both coordinate sets (eq. 4.5): the condition
// is linear in the coordinates, so the least corrections are eliminated and the parameters found
// by Levenberg-Marquardt (Ceres) on the remaining chi-square, from the unweighted solution.
// nullopt when fewer than 2 tie points, a singular normal matrix or no convergence.
std::optional<ConformalTransform2d> FitConformalTransform(const std::vector<PlanarTiePoint>& ties);

// Data snooping with each tie point left out: the transformation fitted to all the other tie
// points, the left-out one's discrepancy current - T(adjacent) and its chi-square under the
// discrepancy's covariance (the tie point's own, the adjacent part rotated and scaled by T, plus
// the fit's eq. 4.8 at that point): chi-square with 2 degrees of freedom when the tie point is no
// outlier and the covariances hold. Unlike the residual of a fit that includes it, an outlier
// cannot pull the fit towards itself, and the covariance is that of the quantity tested. One
// value per tie point, in order; NaN where the others cannot be fitted (fewer than 2 left, or
// FitConformalTransform fails).
std::vector<double> LeaveOneOutChi2(const std::vector<PlanarTiePoint>& ties);

struct SitePairError {
  double traverse_length_m = 0.0;
  double position_sigma_m = 0.0;        // sqrt(trace) of eq. 4.8 at the adjacent site.
  double relative_error_percent = 0.0;  // Eq. 4.9.
  double convergence_current_rad = 0.0;
  double convergence_adjacent_rad = 0.0;
  double mean_distance_ratio = 0.0;  // Fig. 4.19, averaged over the tie points.
  double chi2 = 0.0;                 // v^T Sigma^-1 v of the conformal fit (its residuals).
  int redundancy = 0;                // 2 n - 4.
};

// The a-posteriori variance factor sigma_0^2 pooled over several conformal fits (e.g. a run's
// legs): sum chi2 / sum redundancy, and its one-sided 95 % upper bound sum chi2 / chi2_0.05(r)
// (chi-square quantile of the pooled redundancy r). A factor well below 1 says the tie points'
// a-priori covariances are pessimistic by about 1 / sqrt(factor) in sigma. Fits with redundancy
// 0 are skipped; with none left, estimate and upper bound are NaN. Fits whose worst residuals
// were dropped first (MatchSitePair's outlier test) give a chi2 truncated low: the estimate and
// bound then lean optimistic.
struct PooledVarianceFactor {
  int fits = 0;           // Fits with redundancy > 0.
  double chi2 = 0.0;      // Their summed chi2.
  int redundancy = 0;     // Their summed redundancy.
  double estimate = 0.0;  // sigma_0^2 (dimensionless); NaN when nothing was pooled.
  double upper_95 = 0.0;  // Its one-sided 95 % upper bound; NaN when nothing was pooled.
};
PooledVarianceFactor PoolVarianceFactor(const std::vector<SitePairError>& fits);

// RE of the adjacent site (at the origin of its own frame), given where it lies in the current
// frame (`adjacent_in_current`, for the traverse length and the geometry figures).
std::optional<SitePairError> EvaluateSitePair(const std::vector<PlanarTiePoint>& ties,
                                              const Eigen::Vector2d& adjacent_in_current);

// Convergence angle at a site (Table 4.1 note): the angle between the first and last sights
// that cover all the points, i.e. 2 pi minus the largest azimuth gap [rad]; 0 for < 2 points.
double ConvergenceAngle(const Eigen::Vector2d& site, const std::vector<Eigen::Vector2d>& points);

// Fig. 4.19: min(d1, d2) / max(d1, d2) for distances d1, d2 from the two sites; 0 if both 0.
double DistanceRatio(const Eigen::Vector3d& point, const Eigen::Vector3d& site_a,
                     const Eigen::Vector3d& site_b);

// The configuration study of ch. 4.1.2 (Figs. 4.1-4.5). Sites at (0, 0) and (D, 0) of one frame,
// landmarks in a figure centred half-way (Fig. 4.1): 2 at (D/2, +-s); 3 on an equilateral
// triangle; 4 on a square; 6 on a hexagon; 9 on a square's corners, edge midpoints and centre.
// The figure's size s is set so that the convergence angle at either site is the given one.
struct ConfigurationStudyOptions {
  std::vector<int> landmark_counts = {2, 3, 4, 6, 9};
  std::vector<double> traverse_lengths_m = {7.5, 15.0, 20.0, 25.0};
  double min_convergence_deg = 20.0;
  double max_convergence_deg = 160.0;
  double convergence_step_deg = 5.0;  // >= 0.01
  LocalizationCamera camera;
  void Check() const;  // Throws areomap::Error naming the field.
};

struct ConfigurationSample {
  int landmark_count = 0;
  double traverse_length_m = 0.0;
  double convergence_deg = 0.0;
  double figure_size_m = 0.0;  // Largest landmark distance from the middle [m].
  double position_sigma_m = 0.0;
  double relative_error_percent = 0.0;
};

// Landmark positions of the study's layout (frame above); throws areomap::Error for a count
// other than 2, 3, 4, 6, 9 or a convergence outside (0, 180) degrees.
std::vector<Eigen::Vector2d> StudyLandmarks(int landmark_count, double traverse_length_m,
                                            double convergence_deg);
ConfigurationSample EvaluateConfiguration(int landmark_count, double traverse_length_m,
                                          double convergence_deg, const LocalizationCamera& camera);
std::vector<ConfigurationSample> RunConfigurationStudy(const ConfigurationStudyOptions& options);

}  // namespace areomap
