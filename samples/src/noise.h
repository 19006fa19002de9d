// Seeded 2D gradient noise (Perlin 2002 style) and its fractal sum, for terrain relief and
// albedo texture. No Debian library provides seeded continuous noise, so it lives here.
#pragma once

#include <cstdint>

namespace areomap::internal {

// Gradient noise in about [-1, 1], zero at integer lattice points, C1-continuous.
double GradientNoise(double x, double y, uint32_t seed);

// Fractal sum of `octaves` noise layers: the first has wavelength `wavelength` [m], each next
// one half the wavelength and `gain` times the amplitude. Normalised to unit peak amplitude.
double FractalNoise(double x, double y, double wavelength, int octaves, double gain, uint32_t seed);

}  // namespace areomap::internal
