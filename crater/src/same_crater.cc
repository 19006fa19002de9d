#include "areomap/crater/same_crater.h"

#include <algorithm>

namespace areomap {
namespace {

constexpr double kCentreTolerance = 0.25;  // x the larger diameter
constexpr double kMinRatio = 0.7;          // other / reference diameter
constexpr double kMaxRatio = 1.3;

}  // namespace

bool SameCrater(const CraterCircle& reference, const CraterCircle& other) {
  const double dr = reference.diameter, d = other.diameter;
  if (!(dr > 0.0 && d > 0.0)) return false;
  const double ratio = d / dr;
  return (reference.center - other.center).norm() < kCentreTolerance * std::max(dr, d) &&
         ratio >= kMinRatio && ratio <= kMaxRatio;
}

bool SameCraterEitherWay(const CraterCircle& a, const CraterCircle& b) {
  return SameCrater(a, b) || SameCrater(b, a);
}

bool SameCraterOrConcentric(const CraterCircle& a, const CraterCircle& b) {
  const double lo = 0.5 * std::min(a.diameter, b.diameter);
  const double hi = 0.5 * std::max(a.diameter, b.diameter);
  const double distance = (a.center - b.center).norm();
  return (distance < 0.5 * lo && hi < 1.3 * lo) || (distance < 0.5 * hi && hi < 1.6 * lo);
}

// The other circle at most 1.6x as wide, its centre within half its radius: 0.8 x this radius.
double SameCraterOrConcentricSearchRadius(double diameter) { return 0.4 * diameter; }

double SameCraterSearchRadius(double diameter) { return kCentreTolerance * diameter / kMinRatio; }

}  // namespace areomap
