#include "high_pass.h"

#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>

namespace areomap::internal {

MaskedImage HighPass(const MaskedImage& in, double sigma) {
  // Valid: finite (|v| < inf is false for NaN too) and unmasked; OpenCV's vectorised array
  // operations, as a search window is high-passed on every match.
  cv::Mat valid;
  cv::compare(cv::abs(in.image), std::numeric_limits<float>::infinity(), valid, cv::CMP_LT);
  if (!in.mask.empty()) cv::bitwise_and(valid, in.mask != 0, valid);
  cv::Mat value(in.image.size(), CV_32F, cv::Scalar(0.0f)), weight;
  in.image.copyTo(value, valid);
  valid.convertTo(weight, CV_32F, 1.0 / 255.0);
  cv::Mat blurred_value, blurred_weight;
  cv::GaussianBlur(value, blurred_value, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  cv::GaussianBlur(weight, blurred_weight, cv::Size(), sigma, sigma, cv::BORDER_CONSTANT);
  cv::Mat local_mean;
  cv::divide(blurred_value, blurred_weight, local_mean);
  MaskedImage out{value - local_mean, valid};
  // Undefined where the image is invalid or its neighbourhood holds (nearly) no valid pixel.
  cv::Mat defined;
  cv::compare(blurred_weight, 1e-3, defined, cv::CMP_GT);
  cv::bitwise_and(defined, valid, defined);
  out.image.setTo(std::numeric_limits<float>::quiet_NaN(), defined == 0);
  return out;
}

HighPassedImage::HighPassedImage(const MaskedImage& image, bool whole) : raw_(image) {
  if (whole) whole_ = HighPass(image, kHighPassSigmaPx);
}

MaskedImage HighPassedImage::Reach(const ShiftWindow& shifts, cv::Size size,
                                   ShiftWindow* local) const {
  const int margin = GaussianReachPx(kHighPassSigmaPx);
  const cv::Rect reach =
      cv::Rect(shifts.min_shift_x - margin, shifts.min_shift_y - margin,
               shifts.max_shift_x - shifts.min_shift_x + size.width + 2 * margin,
               shifts.max_shift_y - shifts.min_shift_y + size.height + 2 * margin) &
      cv::Rect(0, 0, raw_.image.cols, raw_.image.rows);
  *local = ShiftWindow{shifts.min_shift_x - reach.x, shifts.max_shift_x - reach.x,
                       shifts.min_shift_y - reach.y, shifts.max_shift_y - reach.y};
  if (reach.empty()) return {};
  const MaskedImage& from = whole_.image.empty() ? raw_ : whole_;
  const MaskedImage crop{from.image(reach), from.mask.empty() ? cv::Mat() : from.mask(reach)};
  return whole_.image.empty() ? HighPass(crop, kHighPassSigmaPx) : crop;
}

}  // namespace areomap::internal
