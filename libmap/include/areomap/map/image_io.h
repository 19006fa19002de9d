// Plain (non-georeferenced) images: PNG, TIFF, JPEG, 8- or 16-bit, 1-4 channels, through
// OpenImageIO. Channels are kept in file order (RGB, not OpenCV's BGR).
#pragma once

#include <filesystem>
#include <optional>

#include <opencv2/core.hpp>

namespace areomap {

// Returns CV_8UC(n) or CV_16UC(n); other pixel types are converted to 16-bit.
// Throws areomap::Error("<path>: ...") if the file is missing or not an image.
cv::Mat ReadImage(const std::filesystem::path& path);

// Writes CV_8UC(n) or CV_16UC(n), n in 1..4, atomically; the format comes from the extension.
// PNG at zlib's fastest level (plots and overlays are written once and looked at).
void WriteImage(const std::filesystem::path& path, const cv::Mat& image);

// The values at quantiles `low` and `high` (0 <= low <= high <= 1) of the finite pixels of a
// single-channel image (of any depth, compared as floats), read at every `step`-th row and
// column; the value at quantile q is the sorted sample's element floor(q (n - 1))
// (std::nth_element, linear time). For contrast stretches of plots. std::nullopt when no sampled
// pixel is finite; throws areomap::Error naming the argument for a multi-channel image, bad
// quantiles or step < 1.
struct ValueRange {
  double low = 0.0;
  double high = 0.0;
};
std::optional<ValueRange> FiniteQuantileRange(const cv::Mat& image, double low, double high,
                                              int step = 1);

// CV_8U mask of `image`'s NaN pixels (areomap's nodata in float rasters): 255 where NaN, else 0;
// all 0 for an integer image. Multi-channel images give a mask per channel. Use it instead of
// `image != image`: OpenCV 4.6's vectorised CMP_NE calls NaN equal to itself on all but the last
// few pixels of a row, so that mask misses nearly every NaN.
cv::Mat NanMask(const cv::Mat& image);

}  // namespace areomap
