// Images less their local mean, as the registration's decision measures correlation on them
// (orbital_match.cc: the chance level and the template parts' consistency). Internal header.
#pragma once

#include <opencv2/core.hpp>

#include "areomap/registration/orbital_pyramid.h"

namespace areomap::internal {

// The local mean removed is a Gaussian of this many orbital pixels: the shading of broad slopes
// and albedo makes wrong shifts of a smooth scene correlate by the tenths everywhere, and hides
// no evidence of where the template fits.
constexpr double kHighPassSigmaPx = 3.0;

// `in` less its local mean (normalized convolution over valid pixels, Gaussian of `sigma` px);
// valid where `in` is (finite and unmasked), NaN elsewhere. A pixel's value depends on the input
// within 4 sigma of it only: a crop of the output equals the output of a crop 4 sigma larger.
MaskedImage HighPass(const MaskedImage& in, double sigma = kHighPassSigmaPx);

}  // namespace areomap::internal
