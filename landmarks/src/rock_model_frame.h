// Internal to the rock model code (shared by rock_model.cc and rock_model_fit.cc): the model
// frame transform of eqs. 2.8-2.11 and the geometric distance to each model surface, templated
// so Ceres can differentiate them. Units: metres and radians; see rock_model.h for the frames.
#pragma once

#include <algorithm>
#include <cmath>
#include <numbers>

#include "areomap/landmarks/rock_model.h"

namespace areomap::rock_model_internal {

// Parameter vector layout used by the fit: h, a, b, phi, alpha, beta, center_x, center_y.
enum Index { kHeight = 0, kA, kB, kPhi, kAlpha, kBeta, kCenterX, kCenterY, kCount };

// p' = Rz(phi) Ry(beta) Rx(alpha) (p - c), the passive rotations of eq. 2.9 (eq. 2.11).
template <typename T>
void ToModelFrame(const T* q, const T& x, const T& y, const T& z, T* out) {
  using std::cos;
  using std::sin;
  const T ca = cos(q[kAlpha]), sa = sin(q[kAlpha]);
  const T cb = cos(q[kBeta]), sb = sin(q[kBeta]);
  const T cg = cos(q[kPhi]), sg = sin(q[kPhi]);
  const T dx = x - q[kCenterX], dy = y - q[kCenterY];
  // Rx(alpha): (x, c y + s z, -s y + c z).
  const T y1 = ca * dy + sa * z, z1 = -sa * dy + ca * z;
  // Ry(beta): (c x - s z, y, s x + c z).
  const T x2 = cb * dx - sb * z1, z2 = sb * dx + cb * z1;
  // Rz(phi): (c x + s y, -s x + c y, z).
  out[0] = cg * x2 + sg * y1;
  out[1] = -sg * x2 + cg * y1;
  out[2] = z2;
}

// Signed geometric distance of model-frame point (u, v, w) to the model surface [m], positive
// outside. `b` is only read for the semi-ellipsoid.
template <typename T>
T SurfaceDistance(RockModelShape shape, const T& u, const T& v, const T& w, const T& h, const T& a,
                  const T& b) {
  using std::sqrt;
  switch (shape) {
    case RockModelShape::kHemispheroid:
    case RockModelShape::kSemiEllipsoid: {
      const T bb = shape == RockModelShape::kSemiEllipsoid ? b : a;
      const T rho = sqrt(u * u / (a * a) + v * v / (bb * bb) + w * w / (h * h) + T(1e-24));
      const T norm = sqrt(u * u + v * v + w * w + T(1e-24));
      return norm * (rho - T(1.0)) / rho;  // Distance along the ray from the centre.
    }
    case RockModelShape::kCone: {
      const T s = sqrt(u * u + v * v + T(1e-18));
      return (s / a + w / h - T(1.0)) / sqrt(T(1.0) / (a * a) + T(1.0) / (h * h));
    }
    case RockModelShape::kTetrahedron: {
      const T inradius = T(0.5) * a;
      const T scale = sqrt(T(1.0) / (inradius * inradius) + T(1.0) / (h * h));
      T best = T(-1e300);
      for (int i = 0; i < 3; ++i) {
        const double angle = std::numbers::pi / 3.0 + 2.0 * std::numbers::pi / 3.0 * i;
        const T d =
            ((u * std::cos(angle) + v * std::sin(angle)) / inradius + w / h - T(1.0)) / scale;
        if (d > best) best = d;
      }
      return best;
    }
  }
  return T(0.0);
}

}  // namespace areomap::rock_model_internal
