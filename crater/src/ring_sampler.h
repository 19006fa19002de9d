// Sampling an image along ellipse rings, internal to the crater module: the detector's bowl
// signature (crater_detector.cc) and the sun azimuth votes (sun_azimuth.cc) read the same rings.
//
// Frame: the ellipse's coordinates (GDAL pixel convention for the detector's images). Failure:
// none; RingStats skips non-finite values and gives NaN without enough of them.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>

#include <Eigen/Core>

#include "areomap/crater/ellipse.h"

namespace areomap::internal {

// Mean and std of `m` along ellipse rings at the given elliptical radii, split by weight sign.
struct RingStats {
  double sum = 0.0, sum2 = 0.0;
  int n = 0;
  void Add(double v) {
    if (!std::isfinite(v)) return;
    sum += v;
    sum2 += v * v;
    ++n;
  }
  double Mean() const { return n > 0 ? sum / n : std::numeric_limits<double>::quiet_NaN(); }
  double Std() const {
    return n > 1 ? std::sqrt(std::max(0.0, sum2 / n - Mean() * Mean()))
                 : std::numeric_limits<double>::quiet_NaN();
  }
};

// Points of the ellipse scaled by rho about its centre at kRingSamples evenly spaced eccentric
// anomalies; the trigonometry is computed once per ellipse (and once for the anomalies).
constexpr int kRingSamples = 48;

class RingSampler {
 public:
  explicit RingSampler(const Ellipse& e) : e_(e), cs_(std::cos(e.angle)), sn_(std::sin(e.angle)) {}

  Eigen::Vector2d Point(double rho, int k) const {
    const auto& [cos_t, sin_t] = Anomalies()[static_cast<size_t>(k)];
    const Eigen::Vector2d local(rho * e_.semi_major * cos_t, rho * e_.semi_minor * sin_t);
    return e_.center +
           Eigen::Vector2d(cs_ * local.x() - sn_ * local.y(), sn_ * local.x() + cs_ * local.y());
  }

 private:
  using Table = std::array<std::pair<double, double>, kRingSamples>;
  static const Table& Anomalies() {
    static const Table table = [] {
      Table t;
      for (int k = 0; k < kRingSamples; ++k) {
        const double angle = 2.0 * std::numbers::pi * k / kRingSamples;
        t[static_cast<size_t>(k)] = {std::cos(angle), std::sin(angle)};
      }
      return t;
    }();
    return table;
  }

  const Ellipse& e_;
  double cs_, sn_;
};

}  // namespace areomap::internal
