// Plain (non-georeferenced) images: PNG, TIFF, JPEG, 8- or 16-bit, 1-4 channels, through
// OpenImageIO. Channels are kept in file order (RGB, not OpenCV's BGR).
#pragma once

#include <filesystem>

#include <opencv2/core.hpp>

namespace areomap {

// Returns CV_8UC(n) or CV_16UC(n); other pixel types are converted to 16-bit.
// Throws areomap::Error("<path>: ...") if the file is missing or not an image.
cv::Mat ReadImage(const std::filesystem::path& path);

// Writes CV_8UC(n) or CV_16UC(n), n in 1..4, atomically; the format comes from the extension.
void WriteImage(const std::filesystem::path& path, const cv::Mat& image);

}  // namespace areomap
