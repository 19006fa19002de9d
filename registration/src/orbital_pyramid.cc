#include "areomap/registration/orbital_pyramid.h"

#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

namespace areomap {

MaskedImage DownsampleMasked(const MaskedImage& level, double min_coverage) {
  const cv::Mat& image = level.image;
  cv::Mat valid = image == image;  // Not NaN.
  if (!level.mask.empty()) valid &= (level.mask != 0);
  const int rows = image.rows + (image.rows % 2), cols = image.cols + (image.cols % 2);
  cv::Mat value(rows, cols, CV_32F, cv::Scalar(0.0f)), weight(rows, cols, CV_32F, cv::Scalar(0.0f));
  const cv::Rect inner(0, 0, image.cols, image.rows);
  image.copyTo(value(inner), valid);
  valid.convertTo(weight(inner), CV_32F, 1.0 / 255.0);
  cv::GaussianBlur(value, value, cv::Size(), 0.7, 0.7, cv::BORDER_CONSTANT);
  cv::GaussianBlur(weight, weight, cv::Size(), 0.7, 0.7, cv::BORDER_CONSTANT);
  cv::Mat small_value, small_weight;
  cv::resize(value, small_value, cv::Size(cols / 2, rows / 2), 0, 0, cv::INTER_AREA);
  cv::resize(weight, small_weight, cv::Size(cols / 2, rows / 2), 0, 0, cv::INTER_AREA);
  MaskedImage out;
  out.image.create(small_value.size(), CV_32F);
  out.mask.create(small_value.size(), CV_8U);
  for (int r = 0; r < out.image.rows; ++r) {
    for (int c = 0; c < out.image.cols; ++c) {
      const float w = small_weight.at<float>(r, c);
      const bool ok = w >= min_coverage;
      out.image.at<float>(r, c) =
          ok ? small_value.at<float>(r, c) / w : std::numeric_limits<float>::quiet_NaN();
      out.mask.at<uchar>(r, c) = ok ? 255 : 0;
    }
  }
  return out;
}

std::vector<MaskedImage> BuildMaskedPyramid(const MaskedImage& base, int levels,
                                            double min_coverage) {
  std::vector<MaskedImage> pyramid{base};
  for (int k = 0; k < levels; ++k)
    pyramid.push_back(DownsampleMasked(pyramid.back(), min_coverage));
  return pyramid;
}

}  // namespace areomap
