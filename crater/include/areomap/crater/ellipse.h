// Ellipse geometry for crater rims: parametric form, implicit conic, exact orthogonal distance.
//
// Frames and units: an Ellipse lives in whatever 2D frame its points use, pixel coordinates
// (x right, y down, as OpenCV) or map coordinates (metres, x east, y north); lengths are in
// that frame's unit and angles are radians measured from +x toward +y. Nothing here knows
// which frame it is; callers keep the two apart.
//
// A valid ellipse has finite fields, semi_major >= semi_minor > 0 and angle in [0, pi)
// (IsValid()); Normalized() brings any ellipse with two positive axes to that form. The
// geometric functions below assume a valid ellipse (or at least two positive finite axes)
// and return NaN otherwise; they never throw.
#pragma once

#include <optional>

#include <Eigen/Core>

namespace areomap {

// Implicit conic A x^2 + B xy + C y^2 + D x + E y + F = 0, stored as (A, B, C, D, E, F).
using ConicCoefficients = Eigen::Matrix<double, 6, 1>;

struct Ellipse {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // [frame unit]
  double semi_major = 0.0;                           // a [frame unit]
  double semi_minor = 0.0;                           // b [frame unit], 0 < b <= a
  double angle = 0.0;  // direction of the major axis from +x toward +y [rad], in [0, pi)

  // Finite fields, semi_major >= semi_minor > 0, angle in [0, pi).
  bool IsValid() const;
  // Finite fields and both semi-axes > 0, in either order and at any angle: a curve the
  // distance functions below are defined for.
  bool HasPositiveAxes() const;
  // Swaps the axes when semi_minor > semi_major (turning angle by pi/2) and wraps angle into
  // [0, pi). The curve is unchanged.
  Ellipse Normalized() const;

  // center + R(angle) (a cos t, b sin t); t is the eccentric anomaly [rad], t = 0 at the
  // end of the major axis in the direction of `angle`.
  Eigen::Vector2d PointAt(double t) const;
  double Eccentricity() const;  // sqrt(1 - b^2/a^2), 0 for a circle
  double MeanRadius() const;    // (a + b) / 2, R_avg of the dissertation's eq. 2.1
  double Area() const;          // pi a b [frame unit^2]

  // Conic of this ellipse scaled so that it equals x'^2/a^2 + y'^2/b^2 - 1 in the ellipse's
  // own frame: negative inside, zero on the curve, positive outside.
  ConicCoefficients ToConic() const;
  // The ellipse described by a conic given up to any non-zero scale. nullopt when the conic
  // is not a real ellipse: a hyperbola or parabola (B^2 - 4AC >= 0), an imaginary ellipse or
  // a single point, non-finite coefficients, or an axis ratio beyond about 1e6 (numerically a
  // parabola).
  static std::optional<Ellipse> FromConic(const ConicCoefficients& conic);

  // Exact orthogonal (Euclidean) distance from p to the curve, negative inside, zero on it.
  // Solved in the canonical frame by Eberly's bisection ("Distance from a point to an
  // ellipse, an ellipsoid, or a hyperellipsoid", Geometric Tools, 2013), with the root
  // variable shifted so points near the major axis keep full precision: accurate to a few
  // ulps of the axes everywhere, including the centre, the axes and inside the evolute
  // (tested against dense sampling to < 1e-10 relative).
  double SignedDistance(const Eigen::Vector2d& p) const;
  // The point of the curve nearest to p (one of them where several are equally near, as for
  // the centre of a circle).
  Eigen::Vector2d ClosestPoint(const Eigen::Vector2d& p) const;
  // Eccentric anomaly t in [0, 2 pi) of ClosestPoint(p).
  double ClosestParameter(const Eigen::Vector2d& p) const;
  // Derivative of SignedDistance(p) with respect to (center.x, center.y, semi_major,
  // semi_minor, angle), holding p fixed: -n^T dX/dparam at the closest point X with outward
  // unit normal n (envelope theorem, exact). Undefined where the closest point is not unique
  // (e.g. p at the centre); the value returned there belongs to one of the closest points.
  Eigen::Matrix<double, 5, 1> SignedDistanceGradient(const Eigen::Vector2d& p) const;
  // SignedDistance(p), and SignedDistanceGradient(p) into *gradient, from one closest-point
  // solve (half the work of calling both; for least-squares cost functions).
  double SignedDistanceWithGradient(const Eigen::Vector2d& p,
                                    Eigen::Matrix<double, 5, 1>* gradient) const;
};

// Wraps angle [rad] into [0, pi): an axis direction, which has no sign.
double WrapAxisAngle(double angle);

}  // namespace areomap
