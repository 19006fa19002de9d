#include "areomap/crater/ellipse.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include "areomap/map/numbers.h"

namespace areomap {
namespace {

// Bisection halts earlier, when the midpoint equals an end (at most ~1100 steps in double,
// typically 50-120).
constexpr int kMaxBisections = 1100;

// Largest axis ratio FromConic accepts; beyond it the conic is numerically a parabola.
constexpr double kMinConicEigenRatio = 1e-12;  // lambda_min / lambda_max = (b/a)^2

// |(x, y)| as Eigen's norm, sqrt(x^2 + y^2): std::hypot's guard against overflow and underflow
// of the squares costs several times the square root (glibc) and cannot matter here (ratios near
// 1, lengths of an image's or a map's scale). One call per edge point and fit iteration (the
// crater detector's geometric fits: 1 % of its time with std::hypot).
double Length(double x, double y) { return Eigen::Vector2d(x, y).norm(); }

// Root u > 0 of G(u) = (r0 z0 / (u + r0 - 1))^2 + (z1 / u)^2 - 1, which is decreasing and
// convex in u, bracketed by [z1, 1] (point inside) or [z1, |(r0 z0, z1)|] (outside). This is
// Eberly's GetRoot with his s shifted to u = s + 1, so that u, and with it x1 = y1 / u, keeps
// full relative precision for points close to the major axis (z1 -> 0). Newton steps from the
// left end first: on a convex decreasing function they approach the root monotonically from
// below (each iterate stays a valid lower bound) and converge quadratically near it; where they
// are slow (far from the root), bisection on the remaining bracket finishes.
double GetRoot(double r0, double r0_minus_1, double z0, double z1, double g) {
  constexpr int kMaxNewtonSteps = 12;
  const double n0 = r0 * z0;
  double u0 = z1;
  double u1 = g < 0.0 ? 1.0 : Length(n0, z1);
  const auto value_at = [&](double u) {
    const double ratio0 = n0 / (u + r0_minus_1);
    const double ratio1 = z1 / u;
    return ratio0 * ratio0 + ratio1 * ratio1 - 1.0;
  };
  double u = u0;
  for (int i = 0; i < kMaxNewtonSteps; ++i) {
    const double ratio0 = n0 / (u + r0_minus_1);
    const double ratio1 = z1 / u;
    const double value = ratio0 * ratio0 + ratio1 * ratio1 - 1.0;
    if (value <= 0.0) return u;  // the root, to rounding (iterates never pass it otherwise)
    u0 = u;
    const double slope = -2.0 * (ratio0 * ratio0 / (u + r0_minus_1) + ratio1 * ratio1 / u);
    const double next = std::min(u - value / slope, u1);
    if (!(next > u)) return u;  // no representable progress: converged
    if (next - u <= 1e-15 * next) {
      // Quadratic convergence: the step is at rounding level.
      return value_at(next) < 0.0 ? u : next;
    }
    u = next;
  }
  for (int i = 0; i < kMaxBisections; ++i) {
    u = 0.5 * (u0 + u1);
    if (u == u0 || u == u1) break;
    const double value = value_at(u);
    if (value > 0.0) {
      u0 = u;
    } else if (value < 0.0) {
      u1 = u;
    } else {
      break;
    }
  }
  return u;
}

// Closest point (x0, x1) of the ellipse (x/e0)^2 + (y/e1)^2 = 1 with e0 >= e1 > 0 to the
// first-quadrant point (y0, y1), y0, y1 >= 0; returns the unsigned distance.
double DistanceFirstQuadrant(double e0, double e1, double y0, double y1, double* x0, double* x1) {
  if (y1 > 0.0) {
    if (y0 > 0.0) {
      const double z0 = y0 / e0;
      const double z1 = y1 / e1;
      const double g = z0 * z0 + z1 * z1 - 1.0;
      if (g != 0.0) {
        const double r0 = (e0 / e1) * (e0 / e1);
        const double r0_minus_1 = ((e0 - e1) * (e0 + e1)) / (e1 * e1);
        const double u = GetRoot(r0, r0_minus_1, z0, z1, g);
        *x0 = r0 * y0 / (u + r0_minus_1);
        *x1 = y1 / u;
        return Length(*x0 - y0, *x1 - y1);
      }
      *x0 = y0;
      *x1 = y1;
      return 0.0;
    }
    // On the minor axis: the nearest point is the minor vertex.
    *x0 = 0.0;
    *x1 = e1;
    return std::abs(y1 - e1);
  }
  // On the major axis: inside the evolute the nearest points are off-axis.
  const double numer0 = e0 * y0;
  const double denom0 = e0 * e0 - e1 * e1;
  if (numer0 < denom0) {
    const double xde0 = numer0 / denom0;
    *x0 = e0 * xde0;
    *x1 = e1 * std::sqrt(std::max(0.0, 1.0 - xde0 * xde0));
    return Length(*x0 - y0, *x1);
  }
  *x0 = e0;
  *x1 = 0.0;
  return std::abs(y0 - e0);
}

struct CanonicalNearest {
  Eigen::Vector2d point;   // closest curve point in the ellipse frame
  double signed_distance;  // negative inside
};

// q is in the ellipse's frame (centre at the origin, major axis along x); any a, b > 0.
CanonicalNearest NearestInCanonicalFrame(double a, double b, const Eigen::Vector2d& q) {
  const bool swap = a < b;
  const double e0 = swap ? b : a;
  const double e1 = swap ? a : b;
  const double y0 = std::abs(swap ? q.y() : q.x());
  const double y1 = std::abs(swap ? q.x() : q.y());
  double x0 = 0.0;
  double x1 = 0.0;
  const double distance = DistanceFirstQuadrant(e0, e1, y0, y1, &x0, &x1);
  Eigen::Vector2d point = swap ? Eigen::Vector2d(x1, x0) : Eigen::Vector2d(x0, x1);
  point.x() = std::copysign(point.x(), q.x());
  point.y() = std::copysign(point.y(), q.y());
  const double u = q.x() / a;
  const double v = q.y() / b;
  const bool inside = u * u + v * v < 1.0;
  return {point, inside ? -distance : distance};
}

Eigen::Vector2d ToCanonical(const Ellipse& e, const Eigen::Vector2d& p) {
  const double c = std::cos(e.angle);
  const double s = std::sin(e.angle);
  const Eigen::Vector2d d = p - e.center;
  return {c * d.x() + s * d.y(), -s * d.x() + c * d.y()};
}

Eigen::Vector2d FromCanonical(const Ellipse& e, const Eigen::Vector2d& q) {
  const double c = std::cos(e.angle);
  const double s = std::sin(e.angle);
  return e.center + Eigen::Vector2d(c * q.x() - s * q.y(), s * q.x() + c * q.y());
}

}  // namespace

double WrapAxisAngle(double angle) {
  if (!std::isfinite(angle)) return kNaN;
  double wrapped = std::fmod(angle, std::numbers::pi);
  if (wrapped < 0.0) wrapped += std::numbers::pi;
  // fmod of a tiny negative angle plus pi rounds to pi itself.
  if (wrapped >= std::numbers::pi) wrapped = 0.0;
  return wrapped;
}

bool Ellipse::HasPositiveAxes() const {
  return std::isfinite(semi_major) && std::isfinite(semi_minor) && semi_major > 0.0 &&
         semi_minor > 0.0 && center.allFinite() && std::isfinite(angle);
}

bool Ellipse::IsValid() const {
  return HasPositiveAxes() && semi_major >= semi_minor && angle >= 0.0 && angle < std::numbers::pi;
}

Ellipse Ellipse::Normalized() const {
  Ellipse e = *this;
  if (e.semi_minor > e.semi_major) {
    std::swap(e.semi_major, e.semi_minor);
    e.angle += 0.5 * std::numbers::pi;
  }
  e.angle = WrapAxisAngle(e.angle);
  return e;
}

Eigen::Vector2d Ellipse::PointAt(double t) const {
  return FromCanonical(*this, {semi_major * std::cos(t), semi_minor * std::sin(t)});
}

double Ellipse::Eccentricity() const {
  if (!HasPositiveAxes()) return kNaN;
  const double ratio = std::min(semi_major, semi_minor) / std::max(semi_major, semi_minor);
  return std::sqrt(std::max(0.0, 1.0 - ratio * ratio));
}

double Ellipse::MeanRadius() const { return 0.5 * (semi_major + semi_minor); }

double Ellipse::Area() const { return std::numbers::pi * semi_major * semi_minor; }

ConicCoefficients Ellipse::ToConic() const {
  const double c = std::cos(angle);
  const double s = std::sin(angle);
  const double ia2 = 1.0 / (semi_major * semi_major);
  const double ib2 = 1.0 / (semi_minor * semi_minor);
  const double a = c * c * ia2 + s * s * ib2;
  const double b = 2.0 * c * s * (ia2 - ib2);
  const double cc = s * s * ia2 + c * c * ib2;
  const double x0 = center.x();
  const double y0 = center.y();
  ConicCoefficients conic;
  conic << a, b, cc, -2.0 * a * x0 - b * y0, -b * x0 - 2.0 * cc * y0,
      a * x0 * x0 + b * x0 * y0 + cc * y0 * y0 - 1.0;
  return conic;
}

std::optional<Ellipse> Ellipse::FromConic(const ConicCoefficients& conic) {
  if (!conic.allFinite()) return std::nullopt;
  const double scale = conic.head<3>().cwiseAbs().maxCoeff();
  if (!(scale > 0.0)) return std::nullopt;
  ConicCoefficients k = conic / scale;
  if (k(0) + k(2) < 0.0) k = -k;  // make the quadratic form's trace positive
  const double a = k(0);
  const double b = k(1);
  const double c = k(2);
  // Eigenvalues of [[A, B/2], [B/2, C]]: both must be positive.
  const double det = a * c - 0.25 * b * b;
  const double lambda_max = 0.5 * (a + c) + std::hypot(0.5 * (a - c), 0.5 * b);
  if (!(lambda_max > 0.0) || !(det > 0.0)) return std::nullopt;
  const double lambda_min = det / lambda_max;
  if (lambda_min < kMinConicEigenRatio * lambda_max) return std::nullopt;

  const double denom = 4.0 * det;  // 4AC - B^2
  const Eigen::Vector2d center((b * k(4) - 2.0 * c * k(3)) / denom,
                               (b * k(3) - 2.0 * a * k(4)) / denom);
  // Value of the conic at the centre; the curve is (p - c)^T M (p - c) = -f0.
  const double f0 = k(5) + 0.5 * (k(3) * center.x() + k(4) * center.y());
  if (!(f0 < 0.0)) return std::nullopt;

  Ellipse e;
  e.center = center;
  e.semi_major = std::sqrt(-f0 / lambda_min);
  e.semi_minor = std::sqrt(-f0 / lambda_max);
  // A - C = k cos(2 phi), B = k sin(2 phi) with k = 1/a^2 - 1/b^2 <= 0.
  e.angle = WrapAxisAngle(0.5 * std::atan2(-b, c - a));
  if (!e.IsValid()) return std::nullopt;
  return e;
}

double Ellipse::SignedDistance(const Eigen::Vector2d& p) const {
  if (!HasPositiveAxes() || !p.allFinite()) return kNaN;
  return NearestInCanonicalFrame(semi_major, semi_minor, ToCanonical(*this, p)).signed_distance;
}

Eigen::Vector2d Ellipse::ClosestPoint(const Eigen::Vector2d& p) const {
  if (!HasPositiveAxes() || !p.allFinite()) return Eigen::Vector2d::Constant(kNaN);
  return FromCanonical(
      *this, NearestInCanonicalFrame(semi_major, semi_minor, ToCanonical(*this, p)).point);
}

double Ellipse::ClosestParameter(const Eigen::Vector2d& p) const {
  if (!HasPositiveAxes() || !p.allFinite()) return kNaN;
  const Eigen::Vector2d x =
      NearestInCanonicalFrame(semi_major, semi_minor, ToCanonical(*this, p)).point;
  double t = std::atan2(x.y() / semi_minor, x.x() / semi_major);
  if (t < 0.0) t += 2.0 * std::numbers::pi;
  if (t >= 2.0 * std::numbers::pi) t = 0.0;
  return t;
}

Eigen::Matrix<double, 5, 1> Ellipse::SignedDistanceGradient(const Eigen::Vector2d& p) const {
  Eigen::Matrix<double, 5, 1> gradient;
  SignedDistanceWithGradient(p, &gradient);
  return gradient;
}

double Ellipse::SignedDistanceWithGradient(const Eigen::Vector2d& p,
                                           Eigen::Matrix<double, 5, 1>* gradient) const {
  if (!HasPositiveAxes() || !p.allFinite()) {
    gradient->setConstant(kNaN);
    return kNaN;
  }
  const double a = semi_major;
  const double b = semi_minor;
  const CanonicalNearest nearest = NearestInCanonicalFrame(a, b, ToCanonical(*this, p));
  const Eigen::Vector2d& x = nearest.point;
  const double cos_t = x.x() / a;
  const double sin_t = x.y() / b;
  // Outward unit normal, in the ellipse frame and in the point frame.
  const Eigen::Vector2d n = Eigen::Vector2d(b * cos_t, a * sin_t).normalized();
  const double c = std::cos(angle);
  const double s = std::sin(angle);
  const Eigen::Vector2d n_world(c * n.x() - s * n.y(), s * n.x() + c * n.y());
  // X(t) = center + R(angle) (a cos t, b sin t); d = n^T (p - X) so dd/dq = -n^T dX/dq.
  *gradient << -n_world.x(), -n_world.y(), -n.x() * cos_t, -n.y() * sin_t,
      n.x() * b * sin_t - n.y() * a * cos_t;
  return nearest.signed_distance;
}

}  // namespace areomap
