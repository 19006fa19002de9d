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

  // cv::GaussianBlur's kernel for a float image and this sigma.
  const int ksize = cvRound(sigma_px * 8.0 + 1.0) | 1;
  const int radius = ksize / 2;
  const cv::Mat kernel = cv::getGaussianKernel(ksize, sigma_px, CV_32F);
  std::vector<float> w(static_cast<size_t>(radius) + 1);
  for (int k = 0; k <= radius; ++k) w[static_cast<size_t>(k)] = kernel.at<float>(radius + k);

  // A view reads its parent image beyond its border (reflected at the parent's border), as
  // GaussianBlur does; the derivatives reflect at the view's border, as Sobel on the smoothed
  // view does.
  cv::Size whole;
  cv::Point offset;
  image.locateROI(whole, offset);
  const std::ptrdiff_t stride = static_cast<std::ptrdiff_t>(image.step1());
  const float* view_origin = image.ptr<float>(0);
  // Columns [inside_begin, inside_end) blur from the parent row directly; the few whose taps
  // leave the parent are summed one by one, in the same order.
  const int inside_begin = std::clamp(radius - offset.x, 0, cols);
  const int inside_end = std::clamp(whole.width - offset.x - radius, inside_begin, cols);

  // Working rows: the ring of 2 radius + 1 rows blurred along, and 3 smoothed rows with one
  // column of reflection on each side.
  const int taps = 2 * radius + 1;
  const size_t smoothed_step = static_cast<size_t>(cols) + 2;
  std::vector<float> memory(static_cast<size_t>(taps) * static_cast<size_t>(cols) +
                            3 * smoothed_step);
  float* along = memory.data();
  float* smoothed = along + static_cast<size_t>(taps) * static_cast<size_t>(cols);
  const auto along_row = [&](int v) {
    return along + static_cast<size_t>(((v % taps) + taps) % taps) * static_cast<size_t>(cols);
  };
  const auto smoothed_row = [&](int s) {
    return smoothed + static_cast<size_t>(s % 3) * smoothed_step + 1;
  };

  const auto blur_along = [&](int v) {  // view row v in [-radius, rows + radius)
    const int parent_row = Reflect101(offset.y + v, whole.height);
    const float* source = view_origin + static_cast<std::ptrdiff_t>(parent_row - offset.y) * stride;
    float* out = along_row(v);
    SymmetricBlur(
        w.data(), radius, inside_end - inside_begin,
        [&](int k) { return source + inside_begin + k; }, out + inside_begin);
    const auto at = [&](int c) { return source[Reflect101(offset.x + c, whole.width) - offset.x]; };
    const auto blur_one = [&](int c) {
      float value = w[0] * at(c);
      for (int k = 1; k <= radius; ++k)
        value += w[static_cast<size_t>(k)] * (at(c - k) + at(c + k));
      out[c] = value;
    };
    for (int c = 0; c < inside_begin; ++c) blur_one(c);
    for (int c = inside_end; c < cols; ++c) blur_one(c);
  };
  int next_along = -radius;
  const auto smooth = [&](int s) {
    while (next_along <= s + radius) blur_along(next_along++);
    float* out = smoothed_row(s);
    SymmetricBlur(
        w.data(), radius, cols, [&](int k) { return along_row(s + k); }, out);
    out[-1] = out[Reflect101(-1, cols)];
    out[cols] = out[Reflect101(cols, cols)];
  };

  int next_smoothed = 0;
  for (int y = 0; y < rows; ++y) {
    while (next_smoothed <= std::min(y + 1, rows - 1)) smooth(next_smoothed++);
    SobelRow(smoothed_row(Reflect101(y - 1, rows)), smoothed_row(y),
             smoothed_row(Reflect101(y + 1, rows)), cols, gx->ptr<float>(y), gy->ptr<float>(y),
             magnitude->ptr<float>(y));
  }
}

}  // namespace areomap
