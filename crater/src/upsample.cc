#include "areomap/crater/upsample.h"

#include <algorithm>
#include <cstdint>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "areomap/map/error.h"
#include "cpu_dispatch.h"

namespace areomap {
namespace {

// cv::resize's weights for a 2x linear upsampling: output 2k + 1 and 2k + 2 lie a quarter and
// three quarters of the way from input k to k + 1.
constexpr float kNear = 0.75f;
constexpr float kFar = 0.25f;

// One input row of `w` >= 2 px interpolated along the row into 2 w px, as cv::resize's
// horizontal pass: the first column is in[0] 1 + in[1] 0 (its tap clamped, the weight kept), the
// last in[w - 1].
AREOMAP_ALSO_FOR_AVX2
void AlongRow(const float* __restrict in, int w, float* __restrict out) {
  out[0] = in[0] * 1.0f + in[1] * 0.0f;
  for (int k = 0; k + 1 < w; ++k) {
    out[2 * k + 1] = in[k] * kNear + in[k + 1] * kFar;
    out[2 * k + 2] = in[k] * kFar + in[k + 1] * kNear;
  }
  out[2 * w - 1] = in[w - 1];
}

// out[x] = a[x] wa + b[x] wb for x in [0, n), as cv::resize's vertical pass; streaming stores
// where SSE2 has them (the output is not read back soon).
void AcrossRows(const float* a, float wa, const float* b, float wb, int n, float* out) {
  int x = 0;
#if defined(__SSE2__)
  for (; x < n && (reinterpret_cast<uintptr_t>(out + x) & 15) != 0; ++x)
    out[x] = a[x] * wa + b[x] * wb;
  const __m128 va = _mm_set1_ps(wa), vb = _mm_set1_ps(wb);
  for (; x + 4 <= n; x += 4) {
    _mm_stream_ps(out + x, _mm_add_ps(_mm_mul_ps(_mm_loadu_ps(a + x), va),
                                      _mm_mul_ps(_mm_loadu_ps(b + x), vb)));
  }
#endif
  for (; x < n; ++x) out[x] = a[x] * wa + b[x] * wb;
}

}  // namespace

void UpsampleTwice(const cv::Mat& image, cv::Mat* out) {
  if (image.type() != CV_32F) {
    throw Error("UpsampleTwice: expected a single-band CV_32F image");
  }
  const int w = image.cols, h = image.rows;
  if (w < 2 || h < 2) {
    cv::resize(image, *out, cv::Size(2 * w, 2 * h), 0, 0, cv::INTER_LINEAR);
    return;
  }
  out->create(2 * h, 2 * w, CV_32F);
  // Input row k gives output rows 2k - 1 (from rows k - 1 and k) and 2k (rows k - 1 and k), and
  // row 0 also output row 0 (rows 0 and 0), row h - 1 output row 2h - 1 (rows h - 1 and h - 1):
  // the taps clamped, the weights kept, as cv::resize does.
  tbb::parallel_for(tbb::blocked_range<int>(0, h, 64), [&](const tbb::blocked_range<int>& rows) {
    std::vector<float> previous(2 * static_cast<size_t>(w)), current(previous.size());
    const int first = rows.begin();
    AlongRow(image.ptr<float>(std::max(0, first - 1)), w, previous.data());
    for (int k = first; k < rows.end(); ++k) {
      AlongRow(image.ptr<float>(k), w, current.data());
      const float* above = previous.data();
      const float* row = current.data();
      if (k == 0) {
        AcrossRows(row, kFar, row, kNear, 2 * w, out->ptr<float>(0));
      } else {
        AcrossRows(above, kNear, row, kFar, 2 * w, out->ptr<float>(2 * k - 1));
        AcrossRows(above, kFar, row, kNear, 2 * w, out->ptr<float>(2 * k));
      }
      if (k == h - 1) AcrossRows(row, kNear, row, kFar, 2 * w, out->ptr<float>(2 * h - 1));
      previous.swap(current);
    }
#if defined(__SSE2__)
    _mm_sfence();  // the streamed rows are visible before the task is seen to end
#endif
  });
}

}  // namespace areomap
