#include "high_pass.h"

#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

namespace areomap::internal {

MaskedImage HighPass(const MaskedImage& in, double sigma) {
  cv::Mat value(in.image.size(), CV_32F, cv::Scalar(0.0f));
  cv::Mat weight(in.image.size(), CV_32F, cv::Scalar(0.0f));
  cv::Mat mask(in.image.size(), CV_8U, cv::Scalar(0));
  for (int r = 0; r < in.image.rows; ++r) {
    for (int c = 0; c < in.image.cols; ++c) {
      const float v = in.image.at<float>(r, c);
      if (!std::isfinite(v) || (!in.mask.empty() && in.mask.at<uchar>(r, c) == 0)) continue;
      value.at<float>(r, c) = v;
      weight.at<float>(r, c) = 1.0f;
      mask.at<uchar>(r, c) = 255;
    }
  }
  cv::Mat blurred_value, blurred_weight;
  cv::GaussianBlur(value, blurred_value, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  cv::GaussianBlur(weight, blurred_weight, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  MaskedImage out;
  out.image.create(in.image.size(), CV_32F);
  out.mask = mask;
  for (int r = 0; r < in.image.rows; ++r) {
    for (int c = 0; c < in.image.cols; ++c) {
      const float w = blurred_weight.at<float>(r, c);
      out.image.at<float>(r, c) = mask.at<uchar>(r, c) && w > 1e-3f
                                      ? value.at<float>(r, c) - blurred_value.at<float>(r, c) / w
                                      : std::numeric_limits<float>::quiet_NaN();
    }
  }
  return out;
}

MaskedImage HighPassReach(const MaskedImage& fixed, const ShiftWindow& shifts, cv::Size size,
                          ShiftWindow* local) {
  const int margin = static_cast<int>(std::ceil(4.0 * kHighPassSigmaPx)) + 1;
  const cv::Rect reach =
      cv::Rect(shifts.min_shift_x - margin, shifts.min_shift_y - margin,
               shifts.max_shift_x - shifts.min_shift_x + size.width + 2 * margin,
               shifts.max_shift_y - shifts.min_shift_y + size.height + 2 * margin) &
      cv::Rect(0, 0, fixed.image.cols, fixed.image.rows);
  *local = ShiftWindow{shifts.min_shift_x - reach.x, shifts.max_shift_x - reach.x,
                       shifts.min_shift_y - reach.y, shifts.max_shift_y - reach.y};
  if (reach.empty()) return {};
  MaskedImage crop{fixed.image(reach), fixed.mask.empty() ? cv::Mat() : fixed.mask(reach)};
  return HighPass(crop, kHighPassSigmaPx);
}

}  // namespace areomap::internal
