#include "areomap/crater/rim_edges.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "cpu_dispatch.h"
#include "edge_scratch.h"

namespace areomap {
namespace {

// AREOMAP_ALSO_FOR_AVX2 (cpu_dispatch.h): the wider registers with native blends and absolute
// values halve the Canny suppression's instructions.

// Pixels whose edges are kept: those whose 5x5 neighbourhood is all valid (edges there see no
// filled values through a 3x3 operator on a smoothed image). Without nodata (the common case)
// that is every pixel at least 2 px inside the border, and no mask is stored.
struct UsableArea {
  cv::Mat mask;       // CV_8U, non-zero = usable; empty: `interior` is the usable area
  cv::Rect interior;  // pixels at least 2 px inside the border
  const uchar* MaskRow(int r) const { return mask.empty() ? nullptr : mask.ptr<uchar>(r); }
};

// Whether every pixel of a CV_32F matrix is finite (cv::checkRange's answer, in one vectorised
// pass).
AREOMAP_ALSO_FOR_AVX2
bool AllFinite(const cv::Mat& m) {
  for (int r = 0; r < m.rows; ++r) {
    const float* v = m.ptr<float>(r);
    int bad = 0;
    for (int c = 0; c < m.cols; ++c) bad |= !(std::abs(v[c]) <= std::numeric_limits<float>::max());
    if (bad != 0) return false;
  }
  return true;
}

// Float copy with nodata filled by the mean of the valid pixels, and the usable area.
// `filled` may share the input's pixels (float input without nodata): read it only.
void PrepareInput(const cv::Mat& input, cv::Mat* filled, UsableArea* usable) {
  if (input.channels() != 1) throw Error("crater edges: expected a single-band raster");
  if (input.depth() == CV_32F) {
    *filled = input;
  } else {
    input.convertTo(*filled, CV_32F);
  }
  usable->interior = cv::Rect(2, 2, std::max(0, filled->cols - 4), std::max(0, filled->rows - 4));
  if (AllFinite(*filled)) return;                           // no nodata
  if (filled->data == input.data) *filled = input.clone();  // the holes are filled below
  cv::Mat valid;
  cv::compare(*filled, *filled, valid, cv::CMP_EQ);  // NaN compares unequal to itself
  cv::Mat finite = cv::abs(*filled) < std::numeric_limits<float>::infinity();
  valid &= finite;
  const double fill = cv::countNonZero(valid) > 0 ? cv::mean(*filled, valid)[0] : 0.0;
  filled->setTo(fill, ~valid);
  cv::erode(valid, usable->mask, cv::Mat::ones(5, 5, CV_8U), cv::Point(-1, -1), 1,
            cv::BORDER_CONSTANT, 0);
}

// Largest value of `m` over the usable area (0 when it is empty).
double UsableMax(const cv::Mat& m, const UsableArea& usable) {
  double max_value = 0.0;
  if (!usable.mask.empty()) {
    cv::minMaxLoc(m, nullptr, &max_value, nullptr, nullptr, usable.mask);
  } else if (!usable.interior.empty()) {
    // cv::minMaxLoc's value without its location bookkeeping, in OpenCV's vector registers.
    const cv::Mat interior = m(usable.interior);
    const float lowest = -std::numeric_limits<float>::infinity();
    cv::v_float32 lanes = cv::vx_setall_f32(lowest);
    float tail = lowest;
    for (int r = 0; r < interior.rows; ++r) {
      const float* v = interior.ptr<float>(r);
      int c = 0;
      for (; c + cv::v_float32::nlanes <= interior.cols; c += cv::v_float32::nlanes) {
        lanes = cv::v_max(lanes, cv::vx_load(v + c));
      }
      for (; c < interior.cols; ++c) tail = std::max(tail, v[c]);
    }
    max_value = std::max(cv::v_reduce_max(lanes), tail);
  }
  return max_value;
}

// Edge maps: kEdge marks an edge; Canny's maps also hold kCandidate (below) and 0.
constexpr uchar kCandidate = 1;
constexpr uchar kEdge = 2;

// Calls f(c) for each c in [begin, end) with row[c] == kEdge, in increasing order; row values
// are 0, kCandidate or kEdge. Edges are sparse: words of 8 pixels without one are skipped.
template <class F>
void ForEachEdge(const uchar* row, int begin, int end, F&& f) {
  constexpr uint64_t kEdgeBits = 0x0202020202020202ull;  // kEdge's bit in each byte
  int c = begin;
  while (c < end) {
    if (c + 8 <= end) {
      uint64_t word;
      std::memcpy(&word, row + c, sizeof(word));
      if ((word & kEdgeBits) == 0) {
        c += 8;
        continue;
      }
    }
    const int stop = std::min(end, c + 8);
    for (; c < stop; ++c) {
      if (row[c] == kEdge) f(c);
    }
  }
}

inline float Bilinear(const cv::Mat& m, float x, float y) {
  // (x, y) in OpenCV's index convention (pixel centre at integers), clamped inside.
  x = std::clamp(x, 0.0f, static_cast<float>(m.cols - 1) - 1e-3f);
  y = std::clamp(y, 0.0f, static_cast<float>(m.rows - 1) - 1e-3f);
  const int c = static_cast<int>(x), r = static_cast<int>(y);
  const float fx = x - static_cast<float>(c), fy = y - static_cast<float>(r);
  const float* r0 = m.ptr<float>(r);
  const float* r1 = m.ptr<float>(r + 1);
  return (1 - fy) * ((1 - fx) * r0[c] + fx * r0[c + 1]) + fy * ((1 - fx) * r1[c] + fx * r1[c + 1]);
}

// The values of ranks `ranks` (0-based, ascending order) among non-negative finite floats: the
// elements std::nth_element would put there, found by a radix pass over the float bits (which
// order like the values for non-negative floats): a histogram of the upper 16 bits locates each
// rank's bin, one more pass gathers those bins' few values, and only they are ordered.
// nth_element on ~10^6 strengths was branch-bound (3 % of a detection's time).
template <size_t N>
std::array<float, N> NonNegativeOrderStatistics(const std::vector<float>& values,
                                                const std::array<size_t, N>& ranks) {
  constexpr int kBinShift = 16;
  const auto bin = [](float v) {
    const float positive_zero = v + 0.0f;  // -0 + 0 = +0, whose bits are 0
    uint32_t bits;
    std::memcpy(&bits, &positive_zero, sizeof(bits));
    return bits >> kBinShift;
  };
  std::vector<uint32_t> count(size_t{1} << (32 - kBinShift), 0);
  for (const float v : values) ++count[bin(v)];
  std::array<uint32_t, N> bins{};
  std::array<size_t, N> below{};
  for (size_t k = 0; k < N; ++k) {
    size_t under = 0;
    uint32_t b = 0;
    while (under + count[b] <= ranks[k]) under += count[b++];
    bins[k] = b;
    below[k] = under;
  }
  std::array<std::vector<float>, N> members;
  for (const float v : values) {
    const uint32_t b = bin(v);
    for (size_t k = 0; k < N; ++k) {
      if (b == bins[k]) members[k].push_back(v);
    }
  }
  std::array<float, N> result{};
  for (size_t k = 0; k < N; ++k) {
    const auto it = members[k].begin() + static_cast<std::ptrdiff_t>(ranks[k] - below[k]);
    std::nth_element(members[k].begin(), it, members[k].end());
    result[k] = *it;
  }
  return result;
}

// Appends the strengths the automatic thresholds are drawn from: every 3rd pixel of every 3rd
// row among rows [row_begin, row_end) of `strength`, usable pixels only.
void SampleStrengths(const cv::Mat& strength, const UsableArea& usable, int row_begin, int row_end,
                     std::vector<float>* values) {
  for (int r = row_begin; r < row_end; r += 3) {
    const float* s = strength.ptr<float>(r);
    const uchar* u = usable.MaskRow(r);
    if (u != nullptr) {
      for (int c = 0; c < strength.cols; c += 3) {
        if (u[c]) values->push_back(s[c]);
      }
    } else if (r >= usable.interior.y && r < usable.interior.br().y) {
      // The sampled columns inside the interior: multiples of 3 in [x, br.x).
      for (int c = (usable.interior.x + 2) / 3 * 3; c < usable.interior.br().x; c += 3) {
        values->push_back(s[c]);
      }
    }
  }
}

// Hysteresis thresholds from sampled strengths (SampleStrengths); false when there are too few
// samples or the image is flat.
bool ThresholdsFromStrengths(const std::vector<float>& values, const EdgeOptions& o, double* high,
                             double* low) {
  if (values.size() < 16) return false;
  const auto rank = [&](double q) {
    return static_cast<size_t>(q * static_cast<double>(values.size() - 1));
  };
  const std::array<float, 3> selected =
      NonNegativeOrderStatistics<3>(values, {rank(0.5), rank(o.high_quantile), values.size() - 1});
  const double median = selected[0], top = selected[1], max_value = selected[2];
  // Rayleigh: median of |gradient| of pure noise = sigma sqrt(2 ln 2).
  const double noise = median / std::sqrt(2.0 * std::log(2.0));
  *high = std::max(top, o.noise_factor * noise);
  *low = o.low_ratio * *high;
  return *high > 1e-6 * (max_value + 1e-30) && *high > 0.0;
}

// Hysteresis thresholds from the strength statistics over usable pixels (every 3rd pixel).
bool AutomaticThresholds(const cv::Mat& strength, const UsableArea& usable, const EdgeOptions& o,
                         double* high, double* low) {
  std::vector<float> values;
  values.reserve(static_cast<size_t>(strength.total() / 9 + 1));
  SampleStrengths(strength, usable, 0, strength.rows, &values);
  return ThresholdsFromStrengths(values, o, high, low);
}

// The loops over a row's separate arrays below have no dependence between iterations; GCC
// cannot prove the arrays distinct and would not vectorise them. (rim_edges.cc is compiled
// without errno from sqrt and without FP-trap semantics, crater/CMakeLists.txt: the loops'
// selects and square roots vectorise then; no value changes.)
#if defined(__GNUC__) && !defined(__clang__)
#define AREOMAP_INDEPENDENT_ITERATIONS _Pragma("GCC ivdep")
#else
#define AREOMAP_INDEPENDENT_ITERATIONS
#endif

// std::clamp's value, on values (a select the compiler vectorises).
inline float Clamp(float v, float lo, float hi) { return v < lo ? lo : (hi < v ? hi : v); }

// Sub-pixel edge points of one pixel row, in batches the compiler vectorises: the edges'
// columns and direction fields are gathered first, then their normals and the two sample
// positions along them, then the samples (scalar loads), then the parabola vertex. The float
// operations are those of one edge at a time (the normal as hypotf's value, the samples as
// Bilinear, clamped inside the matrix): the same points, bit for bit.
class SubPixelRow {
 public:
  explicit SubPixelRow(int cols)
      : size_(static_cast<size_t>(std::max(cols, 0))),
        column_(size_),
        ints_(4 * size_),
        floats_(kFloatArrays * size_) {}

  // Queues the edge at column `c` with direction (dx, dy) (any length); each column at most
  // once per row.
  void Add(int c, float dx, float dy) {
    column_[n_] = c;
    Float(kDx)[n_] = dx;
    Float(kDy)[n_] = dy;
    ++n_;
  }

  // Appends the queued edges of row `r` with a non-zero direction to `out`; empties the queue.
  AREOMAP_ALSO_FOR_AVX2 void Flush(const cv::Mat& strength, int r, RimEdges* out) {
    const size_t n = n_;
    n_ = 0;
    if (n == 0) return;
    const float* dx = Float(kDx);
    const float* dy = Float(kDy);
    float* nx = Float(kNx);
    float* ny = Float(kNy);
    float* norm = Float(kNorm);
    int* c_minus = Int(0);
    int* r_minus = Int(1);
    int* c_plus = Int(2);
    int* r_plus = Int(3);
    float* fx_minus = Float(kFxMinus);
    float* fy_minus = Float(kFyMinus);
    float* fx_plus = Float(kFxPlus);
    float* fy_plus = Float(kFyPlus);
    const int* column = column_.data();
    const float x_max = static_cast<float>(strength.cols - 1) - 1e-3f;
    const float y_max = static_cast<float>(strength.rows - 1) - 1e-3f;
    const float fr = static_cast<float>(r);
    AREOMAP_INDEPENDENT_ITERATIONS
    for (size_t k = 0; k < n; ++k) {
      // hypotf's value (glibc computes it in double and rounds), without its special cases.
      const float length = static_cast<float>(
          std::sqrt(static_cast<double>(dx[k]) * dx[k] + static_cast<double>(dy[k]) * dy[k]));
      // Zero, infinite (an overflowing gradient) or NaN lengths give no direction (norm 0).
      const bool valid = length > 0.0f && length < std::numeric_limits<float>::infinity();
      norm[k] = valid ? length : 0.0f;
      // A zero direction (dropped below) samples the pixel itself, inside the matrix. (The
      // divisions are unconditional and selected after, so that the loop vectorises.)
      const float qx = dx[k] / length, qy = dy[k] / length;
      const float ux = valid ? qx : 0.0f;
      const float uy = valid ? qy : 0.0f;
      nx[k] = ux;
      ny[k] = uy;
      const float fc = static_cast<float>(column[k]);
      const float xm = Clamp(fc - ux, 0.0f, x_max), ym = Clamp(fr - uy, 0.0f, y_max);
      const float xp = Clamp(fc + ux, 0.0f, x_max), yp = Clamp(fr + uy, 0.0f, y_max);
      c_minus[k] = static_cast<int>(xm);
      r_minus[k] = static_cast<int>(ym);
      c_plus[k] = static_cast<int>(xp);
      r_plus[k] = static_cast<int>(yp);
      fx_minus[k] = xm - static_cast<float>(c_minus[k]);
      fy_minus[k] = ym - static_cast<float>(r_minus[k]);
      fx_plus[k] = xp - static_cast<float>(c_plus[k]);
      fy_plus[k] = yp - static_cast<float>(r_plus[k]);
    }
    // The samples' 2 x 2 neighbourhoods and the centre values.
    const float* base = strength.ptr<float>(0);
    const size_t stride = strength.step1();
    const float* centre_row = strength.ptr<float>(r);
    float* m0 = Float(kM0);
    float* s00m = Float(kCorner0);  // sample -: (col, row), (col + 1, row), next row
    float* s01m = Float(kCorner0 + 1);
    float* s10m = Float(kCorner0 + 2);
    float* s11m = Float(kCorner0 + 3);
    float* s00p = Float(kCorner0 + 4);  // sample +
    float* s01p = Float(kCorner0 + 5);
    float* s10p = Float(kCorner0 + 6);
    float* s11p = Float(kCorner0 + 7);
    for (size_t k = 0; k < n; ++k) {
      m0[k] = centre_row[column[k]];
      const float* pm = base + static_cast<size_t>(r_minus[k]) * stride + c_minus[k];
      const float* pp = base + static_cast<size_t>(r_plus[k]) * stride + c_plus[k];
      s00m[k] = pm[0];
      s01m[k] = pm[1];
      s10m[k] = pm[stride];
      s11m[k] = pm[stride + 1];
      s00p[k] = pp[0];
      s01p[k] = pp[1];
      s10p[k] = pp[stride];
      s11p[k] = pp[stride + 1];
    }
    float* delta = Float(kDelta);
    AREOMAP_INDEPENDENT_ITERATIONS
    for (size_t k = 0; k < n; ++k) {
      const float mm = (1 - fy_minus[k]) * ((1 - fx_minus[k]) * s00m[k] + fx_minus[k] * s01m[k]) +
                       fy_minus[k] * ((1 - fx_minus[k]) * s10m[k] + fx_minus[k] * s11m[k]);
      const float mp = (1 - fy_plus[k]) * ((1 - fx_plus[k]) * s00p[k] + fx_plus[k] * s01p[k]) +
                       fy_plus[k] * ((1 - fx_plus[k]) * s10p[k] + fx_plus[k] * s11p[k]);
      const float denom = mm - 2.0f * m0[k] + mp;
      const float vertex = 0.5f * (mm - mp) / denom;
      delta[k] = Clamp(denom < 0.0f ? vertex : 0.0f, -0.5f, 0.5f);
    }
    for (size_t k = 0; k < n; ++k) {
      if (norm[k] == 0.0f) continue;
      RimEdgePoint p;
      p.x = static_cast<float>(column[k]) + 0.5f + delta[k] * nx[k];
      p.y = fr + 0.5f + delta[k] * ny[k];
      p.nx = nx[k];
      p.ny = ny[k];
      p.strength = m0[k];
      out->column.push_back(column[k]);
      out->points.push_back(p);
    }
  }

 private:
  enum FloatArray {
    kDx,
    kDy,
    kNx,
    kNy,
    kNorm,
    kFxMinus,
    kFyMinus,
    kFxPlus,
    kFyPlus,
    kM0,
    kDelta,
    kCorner0,
    kFloatArrays = kCorner0 + 8
  };
  float* Float(int array) { return floats_.data() + static_cast<size_t>(array) * size_; }
  int* Int(int array) { return ints_.data() + static_cast<size_t>(array) * size_; }

  size_t size_;
  size_t n_ = 0;
  std::vector<int> column_;
  std::vector<int> ints_;
  std::vector<float> floats_;
};

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

// Canny's non-maximum suppression and hysteresis, as cv::Canny computes them from 16-bit
// gradients (`gx`, `gy` x `scale`, rounded as ToInt16) with the L2 norm (OpenCV 4.x canny.cpp;
// the same edges): a pixel is a candidate when its squared magnitude dx^2 + dy^2 exceeds `low`
// and is a maximum across its gradient direction, quantised to 0, 45, 90 or 135 degrees at the
// tan(22.5 degree) boundaries in OpenCV's fixed point (along the axes: above the neighbour
// behind, at least the one ahead; along a diagonal: above both), with magnitude 0 outside the
// raster; candidates 8-connected through candidates to one above `high` are edges. Written here
// so that the 16-bit gradients are made row by row (no full-size copies) and the suppression
// runs branch-free (vectorised); cv::Canny spends most of its time in data-dependent branches.
// `map`: (rows + 2) x (cols + 2) CV_8U, pixel (r, c) at (r + 1, c + 1) inside a frame of zeros;
// on return kEdge marks the edges. Returns the number of edges.
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

// `edge_map`: kEdge marks edges. `dx`, `dy`: a direction field (any length, e.g. the gradient),
// normalised per edge point. `count`: the number of edges, or an upper bound (reserved).
RimEdges Collect(const cv::Mat& edge_map, size_t count, const UsableArea& usable,
                 const cv::Mat& strength, const cv::Mat& dx, const cv::Mat& dy, bool signed_normals,
                 double high, double low) {
  RimEdges out;
  out.signed_normals = signed_normals;
  out.high_threshold = high;
  out.low_threshold = low;
  out.rows = strength.rows;
  out.cols = strength.cols;
  out.row_start.assign(static_cast<size_t>(strength.rows) + 1, 0);
  out.points.reserve(count);
  out.column.reserve(count);
  // Usable pixels are never on the 1 px frame; without a mask, only the interior's columns.
  const int c_begin = usable.mask.empty() ? usable.interior.x : 1;
  const int c_end =
      usable.mask.empty() ? usable.interior.x + usable.interior.width : strength.cols - 1;
  SubPixelRow row(strength.cols);
  for (int r = 1; r + 1 < strength.rows; ++r) {
    out.row_start[static_cast<size_t>(r)] = static_cast<int>(out.points.size());
    if (usable.mask.empty() && (r < usable.interior.y || r >= usable.interior.br().y)) continue;
    const uchar* e = edge_map.ptr<uchar>(r);
    const uchar* u = usable.MaskRow(r);
    const float* gx = dx.ptr<float>(r);
    const float* gy = dy.ptr<float>(r);
    ForEachEdge(e, c_begin, c_end, [&](int c) {
      if (u == nullptr || u[c]) row.Add(c, gx[c], gy[c]);
    });
    row.Flush(strength, r, &out);
  }
  for (int r = std::max(1, strength.rows - 1); r <= strength.rows; ++r) {
    out.row_start[static_cast<size_t>(r)] = static_cast<int>(out.points.size());
  }
  return out;
}

RimEdges Empty(const cv::Mat& input, bool signed_normals) {
  RimEdges out;
  out.signed_normals = signed_normals;
  out.high_threshold = 0.0;
  out.low_threshold = 0.0;
  out.rows = input.rows;
  out.cols = input.cols;
  out.row_start.assign(static_cast<size_t>(input.rows) + 1, 0);
  return out;
}

// Smoothed image gradients of a single-band image (blur, Sobel, magnitude), with its usable
// area. The full-size temporaries live in the calling task's scratch when there is one
// (edge_scratch.h), else they are allocated here.
struct ImageGradients {
  ImageGradients(const cv::Mat& image, const EdgeOptions& o) {
    PrepareInput(image, &input, &usable);
    internal::EdgeScratch* scratch = internal::CurrentEdgeScratch();
    const auto temporary = [&](int slot, int type) {
      return scratch != nullptr ? scratch->Get(slot, input.rows, input.cols, type) : cv::Mat();
    };
    magnitude = temporary(0, CV_32F);
    gx = temporary(1, CV_32F);
    gy = temporary(2, CV_32F);
    SmoothedImageGradients(input, o.smoothing_sigma_px, &gx, &gy, &magnitude);
  }
  cv::Mat input;  // float copy, nodata filled (PrepareInput)
  UsableArea usable;
  cv::Mat gx, gy, magnitude;
};

// SampleStrengths' samples of image row `row` (2 <= row < rows - 2) computed from its
// neighbourhood alone: three rows smoothed (the smoothing of a view reads the image beyond it,
// so these are the whole image's smoothed rows), their gradients, the middle row's magnitude.
// The same values as ImageGradients over any window that holds the row 4 px inside, for a
// CV_32F image without nodata within 4 rows of `row`.
void SampleRowStrengths(const cv::Mat& image, int row, const EdgeOptions& o,
                        std::vector<float>* values) {
  cv::Mat gx, gy, magnitude;
  SmoothedImageGradients(image.rowRange(row - 1, row + 2), o.smoothing_sigma_px, &gx, &gy,
                         &magnitude);
  UsableArea middle_row;  // the image's usable columns, 2 px inside its border
  middle_row.interior = cv::Rect(2, 1, image.cols - 4, 1);
  SampleStrengths(magnitude, middle_row, 1, 2, values);
}

// Sub-pixel Canny edges of the image of `g` with the hysteresis thresholds high, low.
RimEdges CannyEdges(const ImageGradients& g, double high, double low) {
  const double max_mag = UsableMax(g.magnitude, g.usable);
  if (!(max_mag > high)) return Empty(g.input, true);
  // cv::Canny's input: 16-bit gradients. Squared in int, they must stay below 2^15 / sqrt(2)
  // per component.
  const double scale = 20000.0 / max_mag;
  // cv::Canny's integer thresholds on the squared magnitude.
  const auto squared_threshold = [&](double t) {
    t = std::min(32767.0, t * scale);
    return static_cast<int>(std::floor(t > 0.0 ? t * t : t));
  };
  internal::EdgeScratch* scratch = internal::CurrentEdgeScratch();
  const int rows = g.input.rows, cols = g.input.cols;
  cv::Mat map = scratch != nullptr ? scratch->Get(3, rows + 2, cols + 2, CV_8U)
                                   : cv::Mat(rows + 2, cols + 2, CV_8U);
  const size_t count = NonMaximumHysteresis(g.gx, g.gy, static_cast<float>(scale),
                                            squared_threshold(low), squared_threshold(high), &map);
  if (count == 0) return Empty(g.input, true);
  return Collect(map(cv::Rect(1, 1, cols, rows)), count, g.usable, g.magnitude, g.gx, g.gy, true,
                 high, low);
}

// The windows DetectImageEdgesInRegions computes edges on. The image is cut into bands of
// kBandRows rows; in each band the regions' parts less than kJoinGap px apart along the row are
// joined into one window. Joining pays because a window costs about 30 us beyond its pixels
// (OpenCV's filter set-up: as much as filtering some 2000 px), and the upsampled crater level's
// regions are runs of 8 px tall blocks: one window per region spent more on the calls and on
// the 4 px margins (1.6x the regions' area) than on the regions. Bands of 64 rows joined across
// 64 px: measured against 16-128 rows and 0-256 px on the bench tile
// (docs/notes/benchmarks-history.md, crater speed round 10). A cut between bands also cuts
// hysteresis 4 px beyond it.
constexpr int kBandRows = 64;
constexpr int kJoinGap = 64;

struct EdgeWindow {
  cv::Rect core;                // the joined parts' extent [image px]
  std::vector<cv::Rect> parts;  // the regions within the band, by left edge [image px]
  RimEdges edges;               // of the window around `core`, in its own pixels
  cv::Point origin;             // the window's top-left corner in the image
};

// The regions' parts in each band of kBandRows rows (band b: rows [b kBandRows, (b + 1)
// kBandRows)), for an image of `rows` rows.
std::vector<std::vector<cv::Rect>> PartsByBand(const std::vector<cv::Rect>& regions, int rows) {
  std::vector<std::vector<cv::Rect>> parts(static_cast<size_t>((rows + kBandRows - 1) / kBandRows));
  for (const cv::Rect& region : regions) {
    if (region.empty()) continue;
    for (int b = region.y / kBandRows; b <= (region.br().y - 1) / kBandRows; ++b) {
      const int band_begin = b * kBandRows;
      const int top = std::max(region.y, band_begin);
      const int bottom = std::min(region.br().y, band_begin + kBandRows);
      parts[static_cast<size_t>(b)].emplace_back(region.x, top, region.width, bottom - top);
    }
  }
  return parts;
}

// The windows of one band's `parts`, by left edge.
std::vector<EdgeWindow> BandWindows(std::vector<cv::Rect> parts) {
  std::sort(parts.begin(), parts.end(),
            [](const cv::Rect& a, const cv::Rect& b) { return a.x < b.x; });
  std::vector<EdgeWindow> windows;
  for (const cv::Rect& part : parts) {
    if (windows.empty() || part.x > windows.back().core.br().x + kJoinGap) windows.emplace_back();
    EdgeWindow& w = windows.back();
    w.core = w.parts.empty() ? part : (w.core | part);
    w.parts.push_back(part);
  }
  return windows;
}

// Appends to `out` the points of `w.edges` in image row `row` inside the window's parts, in
// column order, skipping columns up to `*last_column` (a pixel of overlapping parts comes once);
// updates `*last_column`.
void AppendRowInParts(const EdgeWindow& w, int row, RimEdges* out, int* last_column) {
  const int r = row - w.origin.y;
  for (const cv::Rect& part : w.parts) {
    if (row < part.y || row >= part.br().y) continue;
    const int begin = std::max(part.x, *last_column + 1) - w.origin.x;
    const int end = part.br().x - w.origin.x;
    for (int i = w.edges.FirstInRow(r, begin); i < w.edges.row_start[static_cast<size_t>(r) + 1] &&
                                               w.edges.column[static_cast<size_t>(i)] < end;
         ++i) {
      RimEdgePoint p = w.edges.points[static_cast<size_t>(i)];
      p.x += static_cast<float>(w.origin.x);
      p.y += static_cast<float>(w.origin.y);
      out->points.push_back(p);
      out->column.push_back(w.edges.column[static_cast<size_t>(i)] + w.origin.x);
    }
    *last_column = std::max(*last_column, part.br().x - 1);
  }
}

}  // namespace

int RimEdges::FirstInRow(int row, int col) const {
  const auto begin = column.begin() + row_start[static_cast<size_t>(row)];
  const auto end = column.begin() + row_start[static_cast<size_t>(row) + 1];
  return static_cast<int>(std::lower_bound(begin, end, col) - column.begin());
}

void EdgeOptions::Check() const {
  RequireOption(smoothing_sigma_px > 0.0 && smoothing_sigma_px <= 10.0,
                "EdgeOptions.smoothing_sigma_px", "in (0, 10]");
  RequireOption(high_quantile > 0.0 && high_quantile < 1.0, "EdgeOptions.high_quantile",
                "in (0, 1)");
  RequireOption(noise_factor >= 0.0, "EdgeOptions.noise_factor", ">= 0");
  RequireOption(low_ratio > 0.0 && low_ratio <= 1.0, "EdgeOptions.low_ratio", "in (0, 1]");
}

RimEdges DetectImageEdges(const cv::Mat& image, const EdgeOptions& o) {
  o.Check();
  if (image.rows < 8 || image.cols < 8) return Empty(image, true);
  ImageGradients g(image, o);
  double high = 0.0, low = 0.0;
  if (!AutomaticThresholds(g.magnitude, g.usable, o, &high, &low)) return Empty(image, true);
  return CannyEdges(g, high, low);
}

RimEdges DetectImageEdgesInRegions(const cv::Mat& image, const std::vector<cv::Rect>& regions,
                                   const EdgeOptions& o) {
  o.Check();
  if (image.rows < 8 || image.cols < 8) return Empty(image, true);
  const cv::Rect whole(0, 0, image.cols, image.rows);
  for (const cv::Rect& region : regions) {
    if (region.width < 0 || region.height < 0) {
      throw Error("crater edges: a region has a negative size (" + std::to_string(region.width) +
                  " x " + std::to_string(region.height) + " px)");
    }
    // An empty region selects nothing, wherever it lies (cv::Rect's & of it is (0, 0, 0, 0)).
    if (!region.empty() && (region & whole) != region) {
      throw Error("crater edges: a region lies outside the " + std::to_string(image.cols) + " x " +
                  std::to_string(image.rows) + " px image");
    }
  }
  // In a view of a float image the smoothing reads the pixels beyond the window, so there the
  // gradients are the whole image's (SmoothedImageGradients); the margin keeps a region's pixels
  // inside the window's usable interior (2 px) with their suppression neighbours, covers the
  // smoothing and Sobel reach (4 px) of an input that had to be copied (another depth, nodata
  // filled with the window's mean), and lets hysteresis follow an edge a little way out of its
  // region.
  constexpr int kMargin = 4;
  const auto with_margin = [&](const cv::Rect& r) {
    return cv::Rect(r.x - kMargin, r.y - kMargin, r.width + 2 * kMargin, r.height + 2 * kMargin) &
           whole;
  };
  // Thresholds: the automatic thresholds' statistic over strips of 6 rows every 72 rows (the
  // whole width): 1/12 of its samples, spread over all of the image whatever the regions hold.
  // A strip's two sampled rows are one even, one odd, as in the whole image's sampling: rows of
  // an upsampled image alternate between interpolated and original ones, whose gradients differ
  // (strips of 9 rows sampled 2 even to 1 odd, and moved the threshold by up to 3 %). Every 144
  // rows it also moved by 2-3 %, every 72 by at most 0.7 % (the bench tile, HRSC).
  constexpr int kStripRows = 6, kStripPeriod = 72;
  std::vector<float> values;
  for (int y = 0; y < image.rows; y += kStripPeriod) {
    const cv::Rect strip(0, y, image.cols, std::min(kStripRows, image.rows - y));
    const cv::Rect window = with_margin(strip);
    if (window.height < 8) continue;
    if (image.depth() == CV_32F && AllFinite(image(window))) {
      // Only the sampled rows' gradients (a strip's window computed whole has 7 rows per sample).
      for (int r = strip.y; r < strip.br().y; r += 3) {
        if (r >= window.y + 2 && r < window.br().y - 2) SampleRowStrengths(image, r, o, &values);
      }
      continue;
    }
    const ImageGradients g(image(window), o);
    SampleStrengths(g.magnitude, g.usable, strip.y - window.y, strip.br().y - window.y, &values);
  }
  double high = 0.0, low = 0.0;
  if (!ThresholdsFromStrengths(values, o, &high, &low)) return Empty(image, true);
  // Each band's windows with those thresholds; their points inside the regions, row by row.
  RimEdges out = Empty(image, true);
  out.high_threshold = high;
  out.low_threshold = low;
  std::vector<std::vector<cv::Rect>> parts_by_band = PartsByBand(regions, image.rows);
  for (size_t b = 0; b < parts_by_band.size(); ++b) {
    const int band_begin = static_cast<int>(b) * kBandRows;
    const int band_end = std::min(image.rows, band_begin + kBandRows);
    std::vector<EdgeWindow> windows = BandWindows(std::move(parts_by_band[b]));
    for (EdgeWindow& w : windows) {
      const cv::Rect window = with_margin(w.core);
      w.origin = window.tl();
      w.edges = window.width < 8 || window.height < 8
                    ? Empty(image(window), true)
                    : CannyEdges(ImageGradients(image(window), o), high, low);
    }
    for (int row = band_begin; row < band_end; ++row) {
      int last_column = -1;
      for (const EdgeWindow& w : windows) AppendRowInParts(w, row, &out, &last_column);
      out.row_start[static_cast<size_t>(row) + 1] = static_cast<int>(out.points.size());
    }
  }
  return out;
}

RimEdges DetectDtmCrests(const cv::Mat& dtm, double posting, const EdgeOptions& o) {
  o.Check();
  RequireOption(std::isfinite(posting) && posting > 0.0, "DetectDtmCrests.posting", "> 0");
  if (dtm.rows < 8 || dtm.cols < 8) return Empty(dtm, false);
  cv::Mat input, h;
  UsableArea usable;
  PrepareInput(dtm, &input, &usable);
  cv::GaussianBlur(input, h, cv::Size(), o.smoothing_sigma_px);
  cv::Mat hxx, hyy, hxy;
  cv::Sobel(h, hxx, CV_32F, 2, 0, 3, 0.25);
  cv::Sobel(h, hyy, CV_32F, 0, 2, 3, 0.25);
  cv::Sobel(h, hxy, CV_32F, 1, 1, 3, 0.25);
  cv::Mat strength(h.size(), CV_32F), nx(h.size(), CV_32F), ny(h.size(), CV_32F);
  const float to_metres = static_cast<float>(1.0 / posting);
  for (int r = 0; r < h.rows; ++r) {
    for (int c = 0; c < h.cols; ++c) {
      const float a = hxx.at<float>(r, c), b = hxy.at<float>(r, c), d = hyy.at<float>(r, c);
      const float half_trace = 0.5f * (a + d);
      const float disc = std::sqrt(0.25f * (a - d) * (a - d) + b * b);
      const float lambda = half_trace - disc;  // most negative curvature
      float vx = b, vy = lambda - a;
      if (std::abs(vx) + std::abs(vy) < 1e-12f) {
        vx = lambda - d;
        vy = b;
      }
      float norm = std::hypot(vx, vy);
      if (norm < 1e-20f) {
        vx = 1.0f;
        vy = 0.0f;
        norm = 1.0f;
      }
      if (vx < 0.0f || (vx == 0.0f && vy < 0.0f)) norm = -norm;  // unsigned: fix a sign
      nx.at<float>(r, c) = vx / norm;
      ny.at<float>(r, c) = vy / norm;
      strength.at<float>(r, c) = std::max(0.0f, -lambda) * to_metres;
    }
  }
  double high = 0.0, low = 0.0;
  if (!AutomaticThresholds(strength, usable, o, &high, &low)) return Empty(dtm, false);
  // Non-maximum suppression along the curvature direction, then hysteresis.
  cv::Mat weak(h.size(), CV_8U, cv::Scalar(0)), strong(h.size(), CV_8U, cv::Scalar(0));
  for (int r = 1; r + 1 < h.rows; ++r) {
    for (int c = 1; c + 1 < h.cols; ++c) {
      const float s = strength.at<float>(r, c);
      if (s < low) continue;
      const float ux = nx.at<float>(r, c), uy = ny.at<float>(r, c);
      const float fc = static_cast<float>(c), fr = static_cast<float>(r);
      if (s < Bilinear(strength, fc + ux, fr + uy) || s < Bilinear(strength, fc - ux, fr - uy)) {
        continue;
      }
      weak.at<uchar>(r, c) = 255;
      if (s >= high) strong.at<uchar>(r, c) = 255;
    }
  }
  cv::Mat labels;
  const int n = cv::connectedComponents(weak, labels, 8, CV_32S);
  std::vector<uchar> keep(static_cast<size_t>(n), 0);
  for (int r = 0; r < h.rows; ++r) {
    for (int c = 0; c < h.cols; ++c) {
      if (strong.at<uchar>(r, c)) keep[static_cast<size_t>(labels.at<int>(r, c))] = 1;
    }
  }
  cv::Mat edges(h.size(), CV_8U, cv::Scalar(0));
  for (int r = 0; r < h.rows; ++r) {
    for (int c = 0; c < h.cols; ++c) {
      const int label = labels.at<int>(r, c);
      if (label > 0 && keep[static_cast<size_t>(label)]) edges.at<uchar>(r, c) = kEdge;
    }
  }
  return Collect(edges, static_cast<size_t>(cv::countNonZero(edges)), usable, strength, nx, ny,
                 false, high, low);
}

}  // namespace areomap
