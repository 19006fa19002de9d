#include "areomap/crater/rim_edges.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "edge_scratch.h"

namespace areomap {
namespace {

// Pixels whose edges are kept: those whose 5x5 neighbourhood is all valid (edges there see no
// filled values through a 3x3 operator on a smoothed image). Without nodata (the common case)
// that is every pixel at least 2 px inside the border, and no mask is stored.
struct UsableArea {
  cv::Mat mask;       // CV_8U, non-zero = usable; empty: `interior` is the usable area
  cv::Rect interior;  // pixels at least 2 px inside the border
  const uchar* MaskRow(int r) const { return mask.empty() ? nullptr : mask.ptr<uchar>(r); }
  bool At(int r, int c) const {
    return mask.empty() ? interior.contains(cv::Point(c, r)) : mask.at<uchar>(r, c) != 0;
  }
};

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
  if (cv::checkRange(*filled, true)) return;                // no nodata
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
    cv::minMaxLoc(m(usable.interior), nullptr, &max_value);
  }
  return max_value;
}

float Bilinear(const cv::Mat& m, float x, float y) {
  // (x, y) in OpenCV's index convention (pixel centre at integers), clamped inside.
  x = std::clamp(x, 0.0f, static_cast<float>(m.cols - 1) - 1e-3f);
  y = std::clamp(y, 0.0f, static_cast<float>(m.rows - 1) - 1e-3f);
  const int c = static_cast<int>(x), r = static_cast<int>(y);
  const float fx = x - static_cast<float>(c), fy = y - static_cast<float>(r);
  const float* r0 = m.ptr<float>(r);
  const float* r1 = m.ptr<float>(r + 1);
  return (1 - fy) * ((1 - fx) * r0[c] + fx * r0[c + 1]) + fy * ((1 - fx) * r1[c] + fx * r1[c + 1]);
}

// Hysteresis thresholds from the strength statistics over usable pixels (every 3rd pixel).
bool AutomaticThresholds(const cv::Mat& strength, const UsableArea& usable, const EdgeOptions& o,
                         double* high, double* low) {
  std::vector<float> values;
  values.reserve(static_cast<size_t>(strength.total() / 9 + 1));
  for (int r = 0; r < strength.rows; r += 3) {
    const float* s = strength.ptr<float>(r);
    for (int c = 0; c < strength.cols; c += 3) {
      if (usable.At(r, c)) values.push_back(s[c]);
    }
  }
  if (values.size() < 16) return false;
  // Quantiles selected in increasing rank, each on the part above the previous one (after
  // nth_element every later element is at least the selected one).
  auto above = values.begin();
  const auto quantile = [&](double q) {
    auto it =
        values.begin() + static_cast<std::ptrdiff_t>(q * static_cast<double>(values.size() - 1));
    std::nth_element(it >= above ? above : values.begin(), it, values.end());
    above = it;
    return static_cast<double>(*it);
  };
  const bool median_first = o.high_quantile >= 0.5;
  const double first = quantile(median_first ? 0.5 : o.high_quantile);
  const double second = quantile(median_first ? o.high_quantile : 0.5);
  const double median = median_first ? first : second;
  const double top = median_first ? second : first;
  const double max_value = *std::max_element(above, values.end());
  // Rayleigh: median of |gradient| of pure noise = sigma sqrt(2 ln 2).
  const double noise = median / std::sqrt(2.0 * std::log(2.0));
  *high = std::max(top, o.noise_factor * noise);
  *low = o.low_ratio * *high;
  return *high > 1e-6 * (max_value + 1e-30) && *high > 0.0;
}

RimEdgePoint SubPixel(const cv::Mat& strength, int r, int c, float nx, float ny) {
  const float m0 = strength.at<float>(r, c);
  const float fc = static_cast<float>(c), fr = static_cast<float>(r);
  const float mm = Bilinear(strength, fc - nx, fr - ny);
  const float mp = Bilinear(strength, fc + nx, fr + ny);
  const float denom = mm - 2.0f * m0 + mp;
  float delta = denom < 0.0f ? 0.5f * (mm - mp) / denom : 0.0f;
  delta = std::clamp(delta, -0.5f, 0.5f);
  RimEdgePoint p;
  p.x = static_cast<float>(c) + 0.5f + delta * nx;
  p.y = static_cast<float>(r) + 0.5f + delta * ny;
  p.nx = nx;
  p.ny = ny;
  p.strength = m0;
  return p;
}

// `dx`, `dy`: a direction field (any length, e.g. the gradient), normalised per edge point.
RimEdges Collect(const cv::Mat& edge_mask, const UsableArea& usable, const cv::Mat& strength,
                 const cv::Mat& dx, const cv::Mat& dy, bool signed_normals, double high,
                 double low) {
  RimEdges out;
  out.signed_normals = signed_normals;
  out.high_threshold = high;
  out.low_threshold = low;
  out.rows = strength.rows;
  out.cols = strength.cols;
  out.row_start.assign(static_cast<size_t>(strength.rows) + 1, 0);
  const size_t count = static_cast<size_t>(cv::countNonZero(edge_mask));  // an upper bound
  out.points.reserve(count);
  out.column.reserve(count);
  // Usable pixels are never on the 1 px frame; without a mask, only the interior's columns.
  const int c_begin = usable.mask.empty() ? usable.interior.x : 1;
  const int c_end =
      usable.mask.empty() ? usable.interior.x + usable.interior.width : strength.cols - 1;
  for (int r = 1; r + 1 < strength.rows; ++r) {
    out.row_start[static_cast<size_t>(r)] = static_cast<int>(out.points.size());
    if (usable.mask.empty() && (r < usable.interior.y || r >= usable.interior.br().y)) continue;
    const uchar* e = edge_mask.ptr<uchar>(r);
    const uchar* u = usable.MaskRow(r);
    for (int c = c_begin; c < c_end; ++c) {
      if (!e[c] || (u != nullptr && !u[c])) continue;
      const float gx = dx.at<float>(r, c), gy = dy.at<float>(r, c);
      const float norm = std::hypot(gx, gy);
      if (!(norm > 0.0f)) continue;
      out.column.push_back(c);
      out.points.push_back(SubPixel(strength, r, c, gx / norm, gy / norm));
    }
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
  cv::Mat input;
  UsableArea usable;
  PrepareInput(image, &input, &usable);
  // Full-size temporaries: in the calling task's scratch when there is one (edge_scratch.h),
  // else allocated here.
  internal::EdgeScratch* scratch = internal::CurrentEdgeScratch();
  const auto temporary = [&](int slot, int type) {
    return scratch != nullptr ? scratch->Get(slot, input.rows, input.cols, type) : cv::Mat();
  };
  cv::Mat f = temporary(0, CV_32F);
  cv::GaussianBlur(input, f, cv::Size(), o.smoothing_sigma_px);
  cv::Mat gx = temporary(1, CV_32F), gy = temporary(2, CV_32F);
  cv::Sobel(f, gx, CV_32F, 1, 0, 3, 1.0 / 8.0);
  cv::Sobel(f, gy, CV_32F, 0, 1, 3, 1.0 / 8.0);
  cv::Mat mag = f;  // the smoothed image is not needed any more: its memory holds the magnitude
  cv::magnitude(gx, gy, mag);
  double high = 0.0, low = 0.0;
  if (!AutomaticThresholds(mag, usable, o, &high, &low)) return Empty(image, true);
  const double max_mag = UsableMax(mag, usable);
  if (!(max_mag > high)) return Empty(image, true);
  // Canny takes 16-bit gradients; with L2 magnitudes it squares them in int, so stay below
  // 2^15 / sqrt(2) per component.
  const double scale = 20000.0 / max_mag;
  cv::Mat dx16 = temporary(3, CV_16S), dy16 = temporary(4, CV_16S), edges = temporary(5, CV_8U);
  gx.convertTo(dx16, CV_16S, scale);
  gy.convertTo(dy16, CV_16S, scale);
  cv::Canny(dx16, dy16, edges, low * scale, high * scale, true);
  return Collect(edges, usable, mag, gx, gy, true, high, low);
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
      if (label > 0 && keep[static_cast<size_t>(label)]) edges.at<uchar>(r, c) = 255;
    }
  }
  return Collect(edges, usable, strength, nx, ny, false, high, low);
}

}  // namespace areomap
