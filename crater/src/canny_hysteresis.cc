#include "canny_hysteresis.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <opencv2/core/hal/intrin.hpp>

#include "cpu_dispatch.h"

namespace areomap::internal {
namespace {

// AREOMAP_ALSO_FOR_AVX2 (cpu_dispatch.h): the wider registers with native blends and absolute
// values halve the Canny suppression's instructions.

// cv::Canny's input: `g` x `scale` rounded to 16 bits exactly as cv::Mat::convertTo(CV_16S,
// scale) does (the float product rounded to the nearest integer, saturated; OpenCV's own
// vector operations where it uses them, saturate_cast for the rest).
void ToInt16(const float* g, float scale, int n, short* out) {
  int i = 0;
#if CV_SIMD128
  const cv::v_float32x4 factor = cv::v_setall_f32(scale);
  for (; i + 8 <= n; i += 8) {
    const cv::v_int32x4 lo = cv::v_round(cv::v_load(g + i) * factor);
    const cv::v_int32x4 hi = cv::v_round(cv::v_load(g + i + 4) * factor);
    cv::v_store(out + i, cv::v_pack(lo, hi));
  }
#endif
  for (; i < n; ++i) out[i] = cv::saturate_cast<short>(g[i] * scale);
}

// out[c] = dx[c]^2 + dy[c]^2 for c in [0, n), at most INT_MAX. Usable pixels' gradients stay
// below 2^15 / sqrt(2) per component (the 16-bit scale comes from their largest magnitude), but
// those outside the usable area (a window's border, next to nodata filled with a mean) may
// saturate at -2^15 in both, whose sum 2^31 an int cannot hold; capped, they still exceed every
// usable pixel's magnitude, as before.
AREOMAP_ALSO_FOR_AVX2
void SquaredMagnitudes(const short* dx, const short* dy, int n, int* out) {
  constexpr uint32_t kIntMax = std::numeric_limits<int>::max();
  for (int c = 0; c < n; ++c) {
    const uint32_t sum =
        static_cast<uint32_t>(int{dx[c]} * dx[c]) + static_cast<uint32_t>(int{dy[c]} * dy[c]);
    out[c] = static_cast<int>(sum < kIntMax ? sum : kIntMax);
  }
}

// OpenCV's CANNY_SHIFT and TG22 = round(tan(22.5 degrees) 2^15); tan(67.5 degrees) 2^15 =
// TG22 + 2^16. Unsigned: |dy| 2^15 and |dx| (TG22 + 2^16) fit in 32 bits.
constexpr uint32_t kCannyShift = 15;
constexpr uint32_t kTg22 = 13573;
constexpr uint32_t kTg67 = kTg22 + (1u << (kCannyShift + 1));

// One row of NonMaximumHysteresis's suppression (below): `out[c]` for c in [0, cols) from the
// squared magnitudes of the rows above (`up`), at (`m`) and below (`down`), each readable at
// -1 and cols, and the row's 16-bit gradients. Branch-free, so that the compiler vectorises
// it: the neighbour behind (strict) and ahead along the quantised gradient direction.
AREOMAP_ALSO_FOR_AVX2
void SuppressRow(const int* up, const int* m, const int* down, const short* dx, const short* dy,
                 int cols, int low, int high, uchar* out) {
  for (int c = 0; c < cols; ++c) {
    const int v = m[c], left = m[c - 1], right = m[c + 1];
    const int up_left = up[c - 1], up_mid = up[c], up_right = up[c + 1];
    const int down_left = down[c - 1], down_mid = down[c], down_right = down[c + 1];
    const uint32_t ax = static_cast<uint32_t>(std::abs(int{dx[c]}));
    const uint32_t ay = static_cast<uint32_t>(std::abs(int{dy[c]})) << kCannyShift;
    const bool horizontal = ay < ax * kTg22;
    const bool vertical = ay > ax * kTg67;
    const bool rising = (dx[c] ^ dy[c]) < 0;  // signs differ: gradient up-right or down-left
    const int diagonal_behind = rising ? down_left : up_left;
    const int diagonal_ahead = rising ? up_right : down_right;
    const int axis_behind = horizontal ? left : up_mid;
    const int axis_ahead = horizontal ? right : down_mid;
    const bool axis = horizontal | vertical;
    const int behind = axis ? axis_behind : diagonal_behind;
    const int ahead = axis ? axis_ahead : diagonal_ahead;
    const bool maximum = (v > low) & (v > behind) & ((v > ahead) | (axis & (v == ahead)));
    const int value = maximum ? (v > high ? kEdge : kCandidate) : 0;
    out[c] = static_cast<uchar>(value);
  }
}

}  // namespace

size_t NonMaximumHysteresis(const cv::Mat& gx, const cv::Mat& gy, float scale, int low, int high,
                            cv::Mat* map) {
  const int rows = gx.rows, cols = gx.cols;
  const size_t step = map->step1();
  // The frame stays zero; every other pixel is written below.
  map->row(0).setTo(0);
  map->row(rows + 1).setTo(0);
  map->col(0).setTo(0);
  map->col(cols + 1).setTo(0);
  std::vector<uchar*> stack;
  // The 16-bit gradients and squared magnitudes of the rows above, at and below; magnitudes
  // with one column of zeros on each side.
  struct Row {
    std::vector<short> dx, dy;
    std::vector<int> magnitude;
  };
  std::array<Row, 3> buffers;
  for (Row& row : buffers) {
    row.dx.resize(static_cast<size_t>(cols));
    row.dy.resize(static_cast<size_t>(cols));
    row.magnitude.assign(static_cast<size_t>(cols) + 2, 0);
  }
  Row* padded_above = &buffers[0];
  Row* padded_row = &buffers[1];
  Row* padded_below = &buffers[2];
  const auto load = [&](int r, Row* row) {
    int* out = row->magnitude.data() + 1;
    if (r < 0 || r >= rows) {
      std::fill_n(out, cols, 0);
      return;
    }
    short* qx = row->dx.data();
    short* qy = row->dy.data();
    ToInt16(gx.ptr<float>(r), scale, cols, qx);
    ToInt16(gy.ptr<float>(r), scale, cols, qy);
    SquaredMagnitudes(qx, qy, cols, out);
  };
  load(-1, padded_above);
  load(0, padded_row);
  load(1, padded_below);
  for (int r = 0; r < rows; ++r) {
    if (r > 0) {
      std::swap(padded_above, padded_row);
      std::swap(padded_row, padded_below);
      load(r + 1, padded_below);
    }
    const int* up = padded_above->magnitude.data() + 1;
    const int* m = padded_row->magnitude.data() + 1;
    const int* down = padded_below->magnitude.data() + 1;
    uchar* out = map->ptr<uchar>(r + 1) + 1;
    SuppressRow(up, m, down, padded_row->dx.data(), padded_row->dy.data(), cols, low, high, out);
    ForEachEdge(out, 0, cols, [&](int c) { stack.push_back(out + c); });
  }
  // Hysteresis: a depth-first walk from the seeds; each pixel is pushed once (marked first).
  const std::ptrdiff_t s = static_cast<std::ptrdiff_t>(step);
  const std::array<std::ptrdiff_t, 8> neighbours = {-s - 1, -s, -s + 1, -1, 1, s - 1, s, s + 1};
  size_t edges = stack.size();
  size_t top = stack.size();
  stack.resize(std::max<size_t>(2 * top, 1024));
  while (top > 0) {
    uchar* p = stack[--top];
    if (top + neighbours.size() > stack.size()) stack.resize(2 * stack.size());
    uchar** next = stack.data() + top;
    for (const std::ptrdiff_t o : neighbours) {
      uchar* q = p + o;
      if (*q == kCandidate) {
        *q = kEdge;
        *next++ = q;
      }
    }
    const size_t pushed = static_cast<size_t>(next - (stack.data() + top));
    top += pushed;
    edges += pushed;
  }
  return edges;
}

}  // namespace areomap::internal
