#include "noise.h"

#include <cmath>

namespace areomap::internal {
namespace {

uint32_t Hash(int32_t ix, int32_t iy, uint32_t seed) {
  uint32_t h = seed * 0x9E3779B9u ^ static_cast<uint32_t>(ix) * 0x85EBCA6Bu ^
               static_cast<uint32_t>(iy) * 0xC2B2AE35u;
  h ^= h >> 16;
  h *= 0x7FEB352Du;
  h ^= h >> 15;
  h *= 0x846CA68Bu;
  h ^= h >> 16;
  return h;
}

double Fade(double t) { return t * t * t * (t * (t * 6.0 - 15.0) + 10.0); }

double CornerDot(int32_t ix, int32_t iy, double dx, double dy, uint32_t seed) {
  const double angle = Hash(ix, iy, seed) * (2.0 * 3.14159265358979323846 / 4294967296.0);
  return std::cos(angle) * dx + std::sin(angle) * dy;
}

}  // namespace

double GradientNoise(double x, double y, uint32_t seed) {
  const double fx = std::floor(x);
  const double fy = std::floor(y);
  const auto ix = static_cast<int32_t>(fx);
  const auto iy = static_cast<int32_t>(fy);
  const double dx = x - fx;
  const double dy = y - fy;
  const double n00 = CornerDot(ix, iy, dx, dy, seed);
  const double n10 = CornerDot(ix + 1, iy, dx - 1.0, dy, seed);
  const double n01 = CornerDot(ix, iy + 1, dx, dy - 1.0, seed);
  const double n11 = CornerDot(ix + 1, iy + 1, dx - 1.0, dy - 1.0, seed);
  const double u = Fade(dx);
  const double v = Fade(dy);
  const double bottom = n00 + u * (n10 - n00);
  const double top = n01 + u * (n11 - n01);
  return 1.4142135623730951 * (bottom + v * (top - bottom));
}

double FractalNoise(double x, double y, double wavelength, int octaves, double gain,
                    uint32_t seed) {
  double sum = 0.0;
  double norm = 0.0;
  double amplitude = 1.0;
  double frequency = 1.0 / wavelength;
  for (int i = 0; i < octaves; ++i) {
    sum += amplitude * GradientNoise(x * frequency, y * frequency, seed + 7919u * i);
    norm += amplitude;
    amplitude *= gain;
    frequency *= 2.0;
  }
  return norm > 0.0 ? sum / norm : 0.0;
}

}  // namespace areomap::internal
