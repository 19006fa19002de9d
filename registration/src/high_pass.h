// Images less their local mean, as the registration's decision measures correlation on them
// (orbital_match.cc: the chance level and the template parts' consistency). Internal header.
#pragma once

#include <opencv2/core.hpp>

#include "areomap/registration/masked_ncc.h"
#include "areomap/registration/orbital_pyramid.h"

namespace areomap::internal {

// The local mean removed is a Gaussian of this many orbital pixels: the shading of broad slopes
// and albedo makes wrong shifts of a smooth scene correlate by the tenths everywhere, and hides
// no evidence of where the template fits.
constexpr double kHighPassSigmaPx = 3.0;

// `in` less its local mean (normalized convolution over valid pixels, Gaussian of `sigma` px);
// valid where `in` is (finite and unmasked), NaN elsewhere.
MaskedImage HighPass(const MaskedImage& in, double sigma = kHighPassSigmaPx);

// HighPass of the pixels of `fixed` that a template of `size` at `shifts` reaches, with a margin
// that makes them exact; `*local` is `shifts` on the returned crop. Empty where the shifts reach
// no pixel of `fixed`.
MaskedImage HighPassReach(const MaskedImage& fixed, const ShiftWindow& shifts, cv::Size size,
                          ShiftWindow* local);

}  // namespace areomap::internal
