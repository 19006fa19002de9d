// Analytic rock models (ch. 2.3.2, 2.4, Appendix A, eqs. 2.5-2.13, 3.1-3.4) fitted to a rock's
// surface points by least squares (Ceres).
//
// Frame: the rock frame, metres. Its z axis points up along the normal of the rock's background
// plane (the ground the rock sits on), z = 0 on that plane; x, y span the plane. Rock extraction
// (rock_extraction.h) maps site-frame points into it. A model's base centre is (center_x,
// center_y, 0) and its upright axis is z, tilted by the complex model's angles.
//
// Models (Appendix A, Fig. A.1), in the model frame p' = T (p - c):
//   hemispheroid    u^2/r^2 + v^2/r^2 + w^2/h^2 = 1, w >= 0        (eq. 2.5 / A.1)
//   semi-ellipsoid  u^2/a^2 + v^2/b^2 + w^2/h^2 = 1, w >= 0        (eq. 2.6 / A.2)
//   cone            (u^2 + v^2) = (r/h)^2 (w - h)^2, 0 <= w <= h     (eq. 2.7 / A.3)
//   tetrahedron     apex h above the centroid of a base triangle inscribed in the circle of
//                   radius r, first vertex along the azimuth phi (Fig. A.1d, side a = sqrt(3) r).
// T = Rz(phi) Ry(beta) Rx(alpha) with the passive rotation matrices of eq. 2.9 (eq. 2.8, 2.11).
// Simple models have alpha = beta = 0 (upright). The dissertation treats the semi-ellipsoid as
// symmetric about z (eq. 2.10); an ellipse needs its major-axis direction, so the semi-ellipsoid
// also estimates phi here (as the tetrahedron does).
//
// Fitting minimises the geometric distance of each point to the model surface (radial distance
// for the ellipsoids, perpendicular distance to the generator line for the cone, distance to
// the nearest side face for the tetrahedron) with Levenberg-Marquardt; RMS is then the height
// RMS of eq. 2.13 (z of the point minus the model's z at the point's x, y; the model's z is 0
// off its footprint). 1-sigma of the parameters comes from the fit covariance scaled by the
// residual variance. Per-rock failures (too few points, no convergence, degenerate fit) are a
// flag in the result, never an exception; only invalid options throw areomap::Error.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace areomap {

enum class RockModelShape { kHemispheroid, kSemiEllipsoid, kCone, kTetrahedron };
std::string ToString(RockModelShape shape);
RockModelShape RockModelShapeFromString(std::string_view text);  // Throws areomap::Error.
inline constexpr std::array<RockModelShape, 4> kAllRockModelShapes = {
    RockModelShape::kHemispheroid, RockModelShape::kSemiEllipsoid, RockModelShape::kCone,
    RockModelShape::kTetrahedron};

// Shape parameters of one model. For the hemispheroid, cone and tetrahedron b == a == r.
struct RockModelParameters {
  RockModelShape shape = RockModelShape::kHemispheroid;
  double height = 0.0;    // h [m].
  double a = 0.0;         // r, or the semi-ellipsoid's semi-axis along u [m].
  double b = 0.0;         // Semi-ellipsoid's semi-axis along v (= a otherwise) [m].
  double phi = 0.0;       // Azimuth of the u axis / first triangle vertex [rad].
  double alpha = 0.0;     // Tilt about x [rad] (complex model).
  double beta = 0.0;      // Tilt about y [rad] (complex model).
  double center_x = 0.0;  // Base centre in the rock frame [m].
  double center_y = 0.0;

  double MeanRadius() const { return 0.5 * (a + b); }
  // Height of the model surface above the plane z = 0 at (x, y) of the rock frame, 0 off the
  // footprint: the z_model of eq. 2.13. Where the vertical meets the surface more than once (an
  // overhanging tilted rock) the crossing nearest `z_hint` (the observed z), else the highest;
  // a tilted base may dip below z = 0.
  double SurfaceZ(double x, double y, std::optional<double> z_hint = std::nullopt) const;
  double Volume() const;  // [m^3], eq. 3.1 and its siblings.
  // Area of the curved (or side) surface, not the base [m^2]: exact (eq. 3.3; Legendre's
  // elliptic-integral formula for the semi-ellipsoid; closed forms for cone and tetrahedron).
  double SurfaceAreaExact() const;
  // Knud Thomsen's approximation with p = 1.6075 (eq. 3.4) for the ellipsoids; the exact
  // value for the cone and the tetrahedron.
  double SurfaceAreaApprox() const;
};

struct RockModelFitOptions {
  bool complex_model = false;   // Also estimate alpha and beta (eqs. 2.10-2.12).
  bool estimate_center = true;  // Estimate the base centre (else fixed at the initial guess).
  int min_points = 5;           // Table 4.5: a rock needs >= 5 surface points.
  int max_num_iterations = 50;
  double max_tilt_rad = 0.7;  // Bound on |alpha|, |beta| during the fit.
  // Bounds that keep one-sided, noisy views plausible (extraction sets them from the rock's
  // surface points): size parameters in [min_size_m, max_height_m / max_radius_m], the centre
  // within max_center_offset_m of the initial centre.
  double min_size_m = 1e-3;
  double max_height_m = 20.0;
  double max_radius_m = 20.0;
  double max_center_offset_m = 20.0;
  void Check() const;  // Throws areomap::Error naming the field.
};

struct RockModelFit {
  RockModelParameters parameters;
  bool complex_model = false;
  bool converged = false;  // False: too few points, solver failure or degenerate parameters.
  int point_count = 0;
  double rms_m = 0.0;            // Eq. 2.13 [m].
  double geometric_rms_m = 0.0;  // RMS of the fitted geometric distances [m].
  // 1-sigma of height, a, b, phi, alpha, beta, center_x, center_y (0 where not estimated).
  std::array<double, 8> sigma = {};
  std::string message;  // Why the fit failed, empty on success.
};

// Fits one model to points in the rock frame. `initial` gives the starting centre (and, if
// non-zero, size); unset sizes start from the points' extent.
RockModelFit FitRockModel(const std::vector<Eigen::Vector3d>& points_in_rock, RockModelShape shape,
                          const RockModelFitOptions& options,
                          const std::optional<RockModelParameters>& initial = std::nullopt);

// Fits every shape and returns the fits, the converged one with the smallest eq. 2.13 RMS first.
// Empty fits (all not converged) still come back, with their messages.
std::vector<RockModelFit> FitAllRockModels(
    const std::vector<Eigen::Vector3d>& points_in_rock, const RockModelFitOptions& options,
    const std::optional<RockModelParameters>& initial = std::nullopt);

}  // namespace areomap
