// SmoothedImageGradients (rim_edges.h): Gaussian smoothing, Sobel derivatives and their
// magnitude in one pass over the rows.
//
// cv::GaussianBlur, two cv::Sobel and cv::magnitude make four passes over full-size images, and
// each of OpenCV's filter calls sets up its row buffers afresh (zeroed, with every source row
// copied into a bordered buffer): on the many small windows of the upsampled level that set-up
// outweighed the arithmetic. Here the smoothed image lives only as a ring of rows in cache and
// the outputs are written once.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "areomap/crater/rim_edges.h"
#include "areomap/map/error.h"
#include "cpu_dispatch.h"

namespace areomap {
namespace {

// out[c] = w src[c], for c in [0, n).
AREOMAP_ALSO_FOR_AVX2
void Scaled(const float* __restrict src, float w, int n, float* __restrict out) {
  for (int c = 0; c < n; ++c) out[c] = w * src[c];
}

// out[c] += w (a[c] + b[c]), for c in [0, n): one symmetric pair of a Gaussian's taps.
AREOMAP_ALSO_FOR_AVX2
void AddTapPair(const float* __restrict a, const float* __restrict b, float w, int n,
                float* __restrict out) {
  for (int c = 0; c < n; ++c) out[c] += w * (a[c] + b[c]);
}

// out[c] = w[0] centre[c] + sum over k in [1, radius] of w[k] (tap(-k)[c] + tap(k)[c]), the
// taps summed in that order (the same values whichever way `tap` steps: along a row or across
// rows).
template <typename Tap>
void SymmetricBlur(const float* w, int radius, int n, Tap tap, float* out) {
  Scaled(tap(0), w[0], n, out);
  for (int k = 1; k <= radius; ++k) AddTapPair(tap(-k), tap(k), w[k], n, out);
}

// 3 x 3 Sobel derivatives / 8 of the smoothed rows above, at and below (each readable at -1 and
// n) and their magnitude.
AREOMAP_ALSO_FOR_AVX2
void SobelRow(const float* __restrict up, const float* __restrict mid, const float* __restrict down,
              int n, float* __restrict gx, float* __restrict gy, float* __restrict magnitude) {
  for (int c = 0; c < n; ++c) {
    const float dx =
        (up[c + 1] - up[c - 1]) + 2.0f * (mid[c + 1] - mid[c - 1]) + (down[c + 1] - down[c - 1]);
    const float dy =
        (down[c - 1] + 2.0f * down[c] + down[c + 1]) - (up[c - 1] + 2.0f * up[c] + up[c + 1]);
    const float x = 0.125f * dx, y = 0.125f * dy;
    gx[c] = x;
    gy[c] = y;
    magnitude[c] = std::sqrt(x * x + y * y);
  }
}

int Reflect101(int p, int length) {
  return cv::borderInterpolate(p, length, cv::BORDER_REFLECT_101);
}

// cv::GaussianBlur's kernel for a float image and this sigma, from its centre: w[k] for k in
// [0, radius].
std::vector<float> GaussianHalfKernel(double sigma_px) {
  const int ksize = cvRound(sigma_px * 8.0 + 1.0) | 1;
  const int radius = ksize / 2;
  const cv::Mat kernel = cv::getGaussianKernel(ksize, sigma_px, CV_32F);
  std::vector<float> w(static_cast<size_t>(radius) + 1);
  for (int k = 0; k <= radius; ++k) w[static_cast<size_t>(k)] = kernel.at<float>(radius + k);
  return w;
}

// The Gaussian-smoothed rows of a CV_32F view, made in increasing order: a ring of 2 radius + 1
// rows blurred along, and a ring of the last 3 smoothed rows with one column of reflection on
// each side.
//
// A view reads its parent image beyond its border (reflected at the parent's border), as
// GaussianBlur does; the derivatives reflect at the view's border, as Sobel on the smoothed
// view does.
class SmoothedRows {
 public:
  SmoothedRows(const cv::Mat& image, double sigma_px)
      : cols_(image.cols),
        w_(GaussianHalfKernel(sigma_px)),
        radius_(static_cast<int>(w_.size()) - 1),
        taps_(2 * radius_ + 1),
        stride_(static_cast<std::ptrdiff_t>(image.step1())),
        view_origin_(image.ptr<float>(0)),
        smoothed_step_(static_cast<size_t>(cols_) + 2) {
    image.locateROI(whole_, offset_);
    // Columns [inside_begin, inside_end) blur from the parent row directly; the few whose taps
    // leave the parent are summed one by one, in the same order.
    inside_begin_ = std::clamp(radius_ - offset_.x, 0, cols_);
    inside_end_ = std::clamp(whole_.width - offset_.x - radius_, inside_begin_, cols_);
    memory_.resize(static_cast<size_t>(taps_) * static_cast<size_t>(cols_) + 3 * smoothed_step_);
    along_ = memory_.data();
    smoothed_ = along_ + static_cast<size_t>(taps_) * static_cast<size_t>(cols_);
  }

  // Smooths the rows up to `s` not smoothed yet, in order.
  void SmoothThrough(int s) {
    while (next_smoothed_ <= s) Smooth(next_smoothed_++);
  }

  // Smoothed row `s`, one of the last 3 smoothed, readable at -1 and cols.
  float* Row(int s) { return smoothed_ + static_cast<size_t>(s % 3) * smoothed_step_ + 1; }

 private:
  float* AlongRow(int v) {
    return along_ + static_cast<size_t>(((v % taps_) + taps_) % taps_) * static_cast<size_t>(cols_);
  }

  // View row v in [-radius, rows + radius) blurred along into its ring slot.
  void BlurAlong(int v) {
    const int parent_row = Reflect101(offset_.y + v, whole_.height);
    const float* source =
        view_origin_ + static_cast<std::ptrdiff_t>(parent_row - offset_.y) * stride_;
    float* out = AlongRow(v);
    SymmetricBlur(
        w_.data(), radius_, inside_end_ - inside_begin_,
        [&](int k) { return source + inside_begin_ + k; }, out + inside_begin_);
    const auto at = [&](int c) {
      return source[Reflect101(offset_.x + c, whole_.width) - offset_.x];
    };
    const auto blur_one = [&](int c) {
      float value = w_[0] * at(c);
      for (int k = 1; k <= radius_; ++k)
        value += w_[static_cast<size_t>(k)] * (at(c - k) + at(c + k));
      out[c] = value;
    };
    for (int c = 0; c < inside_begin_; ++c) blur_one(c);
    for (int c = inside_end_; c < cols_; ++c) blur_one(c);
  }

  // Row s blurred across the rows blurred along (those still missing first).
  void Smooth(int s) {
    while (next_along_ <= s + radius_) BlurAlong(next_along_++);
    float* out = Row(s);
    SymmetricBlur(
        w_.data(), radius_, cols_, [&](int k) { return AlongRow(s + k); }, out);
    out[-1] = out[Reflect101(-1, cols_)];
    out[cols_] = out[Reflect101(cols_, cols_)];
  }

  int cols_;
  std::vector<float> w_;
  int radius_;
  int taps_;
  cv::Size whole_;
  cv::Point offset_;
  std::ptrdiff_t stride_;
  const float* view_origin_;
  int inside_begin_ = 0, inside_end_ = 0;
  size_t smoothed_step_;
  std::vector<float> memory_;
  float* along_ = nullptr;
  float* smoothed_ = nullptr;
  int next_along_ = -radius_;
  int next_smoothed_ = 0;
};

}  // namespace

void SmoothedImageGradients(const cv::Mat& image, double sigma_px, cv::Mat* gx, cv::Mat* gy,
                            cv::Mat* magnitude) {
  if (image.type() != CV_32FC1) {
    throw Error("SmoothedImageGradients: expected a single-band 32-bit float image");
  }
  RequireOption(std::isfinite(sigma_px) && sigma_px > 0.0 && sigma_px <= 10.0, "sigma_px",
                "in (0, 10]");
  const int rows = image.rows, cols = image.cols;
  gx->create(rows, cols, CV_32F);
  gy->create(rows, cols, CV_32F);
  magnitude->create(rows, cols, CV_32F);
  if (rows == 0 || cols == 0) return;
  SmoothedRows smoothed(image, sigma_px);
  for (int y = 0; y < rows; ++y) {
    smoothed.SmoothThrough(std::min(y + 1, rows - 1));
    SobelRow(smoothed.Row(Reflect101(y - 1, rows)), smoothed.Row(y),
             smoothed.Row(Reflect101(y + 1, rows)), cols, gx->ptr<float>(y), gy->ptr<float>(y),
             magnitude->ptr<float>(y));
  }
}

}  // namespace areomap
