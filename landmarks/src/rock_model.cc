// Rock model geometry: surface height (eq. 2.13's z_model), volume and surface area (eqs. 3.1,
// 3.3, 3.4 and their siblings for the other shapes).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <vector>

#include "areomap/map/error.h"
#include "rock_model_frame.h"

namespace areomap {

namespace {

constexpr double kThomsenP = 1.6075;  // Knud Thomsen's exponent (eq. 3.4).

// Area of the full ellipsoid with semi-axes x, y, z (Legendre's formula with incomplete
// elliptic integrals; Olver et al., NIST DLMF 19.33.2).
double EllipsoidArea(double x, double y, double z) {
  std::array<double, 3> s = {x, y, z};
  std::sort(s.begin(), s.end(), std::greater<>());
  const double a = s[0], b = s[1], c = s[2];
  if (a - c <= 1e-12 * a) return 4.0 * std::numbers::pi * a * a;  // Sphere.
  const double phi = std::acos(c / a);
  const double k =
      std::sqrt(std::clamp(a * a * (b * b - c * c) / (b * b * (a * a - c * c)), 0.0, 1.0 - 1e-15));
  const double sin_phi = std::sin(phi), cos_phi = std::cos(phi);
  return 2.0 * std::numbers::pi * c * c + 2.0 * std::numbers::pi * a * b / sin_phi *
                                              (std::ellint_2(k, phi) * sin_phi * sin_phi +
                                               std::ellint_1(k, phi) * cos_phi * cos_phi);
}

// Real roots of c2 z^2 + c1 z + c0 = 0.
std::vector<double> QuadraticRoots(double c2, double c1, double c0) {
  if (std::abs(c2) < 1e-15) {
    if (std::abs(c1) < 1e-15) return {};
    return {-c0 / c1};
  }
  const double disc = c1 * c1 - 4.0 * c2 * c0;
  if (disc < 0.0) return {};
  const double root = std::sqrt(disc);
  return {(-c1 + root) / (2.0 * c2), (-c1 - root) / (2.0 * c2)};
}

}  // namespace

std::string ToString(RockModelShape shape) {
  switch (shape) {
    case RockModelShape::kHemispheroid:
      return "hemispheroid";
    case RockModelShape::kSemiEllipsoid:
      return "semi-ellipsoid";
    case RockModelShape::kCone:
      return "cone";
    case RockModelShape::kTetrahedron:
      return "tetrahedron";
  }
  return "unknown";
}

RockModelShape RockModelShapeFromString(std::string_view text) {
  for (RockModelShape s : kAllRockModelShapes) {
    if (ToString(s) == text) return s;
  }
  throw Error("unknown rock model '" + std::string(text) +
              "': expected hemispheroid, semi-ellipsoid, cone or tetrahedron");
}

double RockModelParameters::SurfaceZ(double x, double y, std::optional<double> z_hint) const {
  using namespace rock_model_internal;
  const double q[kCount] = {height, a, b, phi, alpha, beta, center_x, center_y};
  // Model-frame line p'(z) = p0 + z t for the vertical through (x, y).
  double p0[3], p1[3];
  ToModelFrame(q, x, y, 0.0, p0);
  ToModelFrame(q, x, y, 1.0, p1);
  const double t[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
  const double tolerance = 1e-9 * std::max(height, a);
  std::vector<double> crossings;  // Heights where the vertical meets the model surface.
  switch (shape) {
    case RockModelShape::kHemispheroid:
    case RockModelShape::kSemiEllipsoid: {
      const double bb = shape == RockModelShape::kSemiEllipsoid ? b : a;
      const double w[3] = {1.0 / (a * a), 1.0 / (bb * bb), 1.0 / (height * height)};
      double c2 = 0, c1 = 0, c0 = -1.0;
      for (int i = 0; i < 3; ++i) {
        c2 += w[i] * t[i] * t[i];
        c1 += 2.0 * w[i] * p0[i] * t[i];
        c0 += w[i] * p0[i] * p0[i];
      }
      for (double z : QuadraticRoots(c2, c1, c0)) {
        if (p0[2] + z * t[2] >= -tolerance) crossings.push_back(z);
      }
      break;
    }
    case RockModelShape::kCone: {
      // u^2 + v^2 = k^2 (h - w)^2 with 0 <= w <= h.
      const double k2 = a * a / (height * height);
      const double e0 = height - p0[2], e1 = -t[2];
      const double c2 = t[0] * t[0] + t[1] * t[1] - k2 * e1 * e1;
      const double c1 = 2.0 * (p0[0] * t[0] + p0[1] * t[1]) - 2.0 * k2 * e0 * e1;
      const double c0 = p0[0] * p0[0] + p0[1] * p0[1] - k2 * e0 * e0;
      for (double z : QuadraticRoots(c2, c1, c0)) {
        const double w = p0[2] + z * t[2];
        if (w >= -tolerance && w <= height + tolerance) crossings.push_back(z);
      }
      break;
    }
    case RockModelShape::kTetrahedron: {
      // Upper surface of the convex solid: the lowest of the upward-facing side planes.
      const double inradius = 0.5 * a;
      double best = std::numeric_limits<double>::infinity();
      for (int i = 0; i < 3; ++i) {
        const double angle = std::numbers::pi / 3.0 + 2.0 * std::numbers::pi / 3.0 * i;
        const double nx = std::cos(angle) / inradius, ny = std::sin(angle) / inradius;
        const double denom = nx * t[0] + ny * t[1] + t[2] / height;
        const double num = 1.0 - nx * p0[0] - ny * p0[1] - p0[2] / height;
        if (denom > 1e-12) best = std::min(best, num / denom);
      }
      if (std::isfinite(best) && p0[2] + best * t[2] >= -tolerance) crossings.push_back(best);
      break;
    }
  }
  if (crossings.empty()) return 0.0;
  double z = *std::max_element(crossings.begin(), crossings.end());
  if (z_hint) {
    for (double c : crossings) {
      if (std::abs(c - *z_hint) < std::abs(z - *z_hint)) z = c;
    }
  }
  return z;
}

double RockModelParameters::Volume() const {
  switch (shape) {
    case RockModelShape::kHemispheroid:
      return 2.0 / 3.0 * std::numbers::pi * a * a * height;  // Eq. 3.1.
    case RockModelShape::kSemiEllipsoid:
      return 2.0 / 3.0 * std::numbers::pi * a * b * height;
    case RockModelShape::kCone:
      return std::numbers::pi * a * a * height / 3.0;
    case RockModelShape::kTetrahedron:
      return std::sqrt(3.0) / 4.0 * a * a * height;  // Base 3 sqrt(3)/4 r^2, times h / 3.
  }
  return 0.0;
}

double RockModelParameters::SurfaceAreaExact() const {
  switch (shape) {
    case RockModelShape::kHemispheroid:
      return 0.5 * EllipsoidArea(a, a, height);  // Eq. 3.3 in closed form.
    case RockModelShape::kSemiEllipsoid:
      return 0.5 * EllipsoidArea(a, b, height);
    case RockModelShape::kCone:
      return std::numbers::pi * a * std::hypot(a, height);
    case RockModelShape::kTetrahedron:
      // Three side faces on base edges sqrt(3) r with slant height sqrt(h^2 + (r / 2)^2).
      return 1.5 * std::sqrt(3.0) * a * std::hypot(height, 0.5 * a);
  }
  return 0.0;
}

double RockModelParameters::SurfaceAreaApprox() const {
  const double p = kThomsenP;
  switch (shape) {
    case RockModelShape::kHemispheroid:
      return 2.0 * std::numbers::pi *
             std::pow((std::pow(a, 2 * p) + 2.0 * std::pow(a * height, p)) / 3.0, 1.0 / p);
    case RockModelShape::kSemiEllipsoid:
      return 2.0 * std::numbers::pi *
             std::pow(
                 (std::pow(a * b, p) + std::pow(a * height, p) + std::pow(b * height, p)) / 3.0,
                 1.0 / p);
    case RockModelShape::kCone:
    case RockModelShape::kTetrahedron:
      return SurfaceAreaExact();
  }
  return 0.0;
}

}  // namespace areomap
