// Image pyramids with validity masks, for coarse-to-fine masked correlation.
//
// Level k+1 pixel (i, j) is the filtered mean of level-k pixels (2i..2i+1, 2j..2j+1), so an
// integer shift x at level k+1 is shift 2x at level k exactly (both images use the same rule).
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace areomap {

struct MaskedImage {
  cv::Mat image;  // CV_32FC1; NaN where invalid.
  cv::Mat mask;   // CV_8UC1, nonzero = valid (an empty mask: every finite pixel is valid).
};

// Halves `level` (odd sizes are padded with invalid pixels): a Gaussian of sigma 0.7 px then a
// 2 x 2 mean, both over valid pixels only (normalized convolution). A coarse pixel is valid if
// at least `min_coverage` of its weight comes from valid pixels. Inputs must be CV_32FC1.
MaskedImage DownsampleMasked(const MaskedImage& level, double min_coverage = 0.75);

// Level 0 (the input) and `levels` halvings.
std::vector<MaskedImage> BuildMaskedPyramid(const MaskedImage& base, int levels,
                                            double min_coverage = 0.75);

}  // namespace areomap
