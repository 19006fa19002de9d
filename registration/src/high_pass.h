// Images less their local mean, as the registration's decision measures correlation on them
// (orbital_match.cc: the chance level and the template parts' consistency). Internal header.
#pragma once

#include <cmath>

#include <opencv2/core.hpp>

#include "areomap/registration/masked_ncc.h"
#include "areomap/registration/orbital_pyramid.h"

namespace areomap::internal {

// The local mean removed is a Gaussian of this many orbital pixels: the shading of broad slopes
// and albedo makes wrong shifts of a smooth scene correlate by the tenths everywhere, and hides
// no evidence of where the template fits.
constexpr double kHighPassSigmaPx = 3.0;

// Pixels beyond which OpenCV's Gaussian of `sigma` px (floating-point images: its kernel reaches
// 4 sigma) gives no weight: a crop grown by this much blurs exactly as the whole image does.
inline int GaussianReachPx(double sigma) { return static_cast<int>(std::ceil(4.0 * sigma)) + 1; }

// `in` less its local mean (normalized convolution over valid pixels, Gaussian of `sigma` px);
// valid where `in` is (finite and unmasked), NaN elsewhere. A pixel's value depends on the input
// within 4 sigma of it only: a crop of the output equals the output of a crop 4 sigma larger.
MaskedImage HighPass(const MaskedImage& in, double sigma = kHighPassSigmaPx);

// An image to correlate high-passed (kHighPassSigmaPx): high-passed whole at once where the
// correlations reach most of it, or crop by crop where they reach a few parts of a large one.
// Both give the same values.
class HighPassedImage {
 public:
  HighPassedImage() = default;
  // With `whole`, all of `image` is high-passed now; otherwise each Reach high-passes its crop.
  HighPassedImage(const MaskedImage& image, bool whole);

  cv::Size size() const { return raw_.image.size(); }
  // The pixels a template of `size` at `shifts` reaches, high-passed, with a margin around them
  // (high-passed crop by crop, the margin's own pixels are not exact: they serve the high pass);
  // `*local` is `shifts` on the returned crop. Empty where the shifts reach no pixel.
  MaskedImage Reach(const ShiftWindow& shifts, cv::Size size, ShiftWindow* local) const;

 private:
  MaskedImage raw_;
  MaskedImage whole_;  // Empty unless high-passed whole.
};

}  // namespace areomap::internal
