#include "areomap/registration/orbital_pyramid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

namespace areomap {
namespace {

// The Gaussian of sigma 0.7 px followed by the 2 x 2 mean, as one 1-D kernel applied at every
// second pixel: out(c) = sum_t kTaps[t] in(2c + t - 3). OpenCV's Gaussian for float images
// reaches 4 sigma (7 taps: cv::getGaussianKernel); the mean of two neighbours adds one tap.
constexpr int kHalfGaussian = 3;
constexpr int kTapCount = 2 * kHalfGaussian + 2;

std::array<float, kTapCount> DownsampleTaps() {
  const cv::Mat g = cv::getGaussianKernel(2 * kHalfGaussian + 1, 0.7, CV_32F);
  std::array<float, kTapCount> taps{};
  for (int t = 0; t < kTapCount; ++t) {
    const float left = t < 2 * kHalfGaussian + 1 ? g.at<float>(t) : 0.0f;
    const float right = t >= 1 ? g.at<float>(t - 1) : 0.0f;
    taps[t] = 0.5f * (left + right);
  }
  return taps;
}

}  // namespace

// Blur, 2 x 2 mean and decimation fused into one separable filter that computes only the kept
// pixels (about a third of the arithmetic of blurring at full resolution, which a level of a
// large search window, millions of pixels, otherwise spends): first along rows into a half-width
// image, then along columns. Value x validity and validity are filtered together; pixels beyond
// the image (and the padding of odd sizes) are 0 in both, as the blur's constant border was.
MaskedImage DownsampleMasked(const MaskedImage& level, double min_coverage) {
  static const std::array<float, kTapCount> taps = DownsampleTaps();
  const cv::Mat& image = level.image;
  const int rows = image.rows, cols = image.cols;
  const int out_rows = (rows + 1) / 2, out_cols = (cols + 1) / 2;
  // Along rows: value and weight of row r at every second column.
  cv::Mat half_value(rows, out_cols, CV_32F), half_weight(rows, out_cols, CV_32F);
  tbb::parallel_for(tbb::blocked_range<int>(0, rows), [&](const tbb::blocked_range<int>& range) {
    // The row's value x validity and validity, with kHalfGaussian + 1 zeros either side.
    std::vector<float> value(cols + 2 * (kHalfGaussian + 1)), weight(value.size());
    for (int r = range.begin(); r != range.end(); ++r) {
      const float* in = image.ptr<float>(r);
      const uchar* mask = level.mask.empty() ? nullptr : level.mask.ptr<uchar>(r);
      std::fill(value.begin(), value.end(), 0.0f);
      std::fill(weight.begin(), weight.end(), 0.0f);
      for (int x = 0; x < cols; ++x) {
        const bool ok = in[x] == in[x] && (mask == nullptr || mask[x] != 0);  // Not NaN.
        value[x + kHalfGaussian + 1] = ok ? in[x] : 0.0f;
        weight[x + kHalfGaussian + 1] = ok ? 1.0f : 0.0f;
      }
      float* hv = half_value.ptr<float>(r);
      float* hw = half_weight.ptr<float>(r);
      for (int c = 0; c < out_cols; ++c) {
        // Padded index of pixel 2c + t - kHalfGaussian.
        const float* pv = value.data() + 2 * c + 1;
        const float* pw = weight.data() + 2 * c + 1;
        float v = 0.0f, w = 0.0f;
        for (int t = 0; t < kTapCount; ++t) {
          v += taps[t] * pv[t];
          w += taps[t] * pw[t];
        }
        hv[c] = v;
        hw[c] = w;
      }
    }
  });
  // Along columns: every second row.
  MaskedImage out{cv::Mat(out_rows, out_cols, CV_32F), cv::Mat(out_rows, out_cols, CV_8U)};
  const float coverage = static_cast<float>(min_coverage);
  tbb::parallel_for(
      tbb::blocked_range<int>(0, out_rows), [&](const tbb::blocked_range<int>& range) {
        std::vector<float> weight(out_cols);  // One row's, reused along the range.
        for (int r = range.begin(); r != range.end(); ++r) {
          float* value = out.image.ptr<float>(r);
          uchar* valid = out.mask.ptr<uchar>(r);
          std::fill(value, value + out_cols, 0.0f);
          std::fill(weight.begin(), weight.end(), 0.0f);
          for (int t = 0; t < kTapCount; ++t) {
            const int y = 2 * r + t - kHalfGaussian;
            if (y < 0 || y >= rows) continue;
            const float* hv = half_value.ptr<float>(y);
            const float* hw = half_weight.ptr<float>(y);
            for (int c = 0; c < out_cols; ++c) {
              value[c] += taps[t] * hv[c];
              weight[c] += taps[t] * hw[c];
            }
          }
          for (int c = 0; c < out_cols; ++c) {
            const bool ok = weight[c] >= coverage;
            value[c] = ok ? value[c] / weight[c] : std::numeric_limits<float>::quiet_NaN();
            valid[c] = ok ? 255 : 0;
          }
        }
      });
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
