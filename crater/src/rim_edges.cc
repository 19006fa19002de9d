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
#include "canny_hysteresis.h"
#include "cpu_dispatch.h"
#include "edge_scratch.h"

namespace areomap {
namespace {

using internal::ForEachEdge;
using internal::kEdge;
using internal::NonMaximumHysteresis;

// AREOMAP_ALSO_FOR_AVX2 (cpu_dispatch.h): the per-pixel loops marked with it also get an AVX2
// build (the Canny suppression's, canny_hysteresis.cc, gain the most).

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
    NormalsAndSamplePositions(strength, r, n);
    GatherSamples(strength, r, n);
    ParabolaVertices(n);
    AppendPoints(r, n, out);
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

  // The steps of Flush, each one loop over the `n` queued edges of row `r` (inlined there, so
  // that they vectorise in its AVX2 build too).

  // The unit normals (norm 0: no direction) and the two sample positions one pixel behind and
  // ahead along them, as the top-left pixel of their 2 x 2 neighbourhood and the fractions.
  void NormalsAndSamplePositions(const cv::Mat& strength, int r, size_t n) {
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
  }

  // The samples' 2 x 2 neighbourhoods and the centre values.
  void GatherSamples(const cv::Mat& strength, int r, size_t n) {
    const int* column = column_.data();
    const int* c_minus = Int(0);
    const int* r_minus = Int(1);
    const int* c_plus = Int(2);
    const int* r_plus = Int(3);
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
  }

  // The sub-pixel offset along the normal: the vertex of the parabola through the two samples
  // and the centre, within half a pixel (0 where the strength does not peak).
  void ParabolaVertices(size_t n) {
    const float* fx_minus = Float(kFxMinus);
    const float* fy_minus = Float(kFyMinus);
    const float* fx_plus = Float(kFxPlus);
    const float* fy_plus = Float(kFyPlus);
    const float* m0 = Float(kM0);
    const float* s00m = Float(kCorner0);
    const float* s01m = Float(kCorner0 + 1);
    const float* s10m = Float(kCorner0 + 2);
    const float* s11m = Float(kCorner0 + 3);
    const float* s00p = Float(kCorner0 + 4);
    const float* s01p = Float(kCorner0 + 5);
    const float* s10p = Float(kCorner0 + 6);
    const float* s11p = Float(kCorner0 + 7);
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
  }

  // The edge points with a direction, in column order.
  void AppendPoints(int r, size_t n, RimEdges* out) {
    const int* column = column_.data();
    const float* nx = Float(kNx);
    const float* ny = Float(kNy);
    const float* norm = Float(kNorm);
    const float* m0 = Float(kM0);
    const float* delta = Float(kDelta);
    const float fr = static_cast<float>(r);
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

  size_t size_;
  size_t n_ = 0;
  std::vector<int> column_;
  std::vector<int> ints_;
  std::vector<float> floats_;
};

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
