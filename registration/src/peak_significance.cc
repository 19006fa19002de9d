#include "areomap/registration/peak_significance.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace areomap {

SurfaceNull MeasureSurfaceNull(const cv::Mat& surface, const cv::Mat& null_mask, int block_px) {
  SurfaceNull out;
  if (surface.empty() || surface.type() != CV_32F || null_mask.size() != surface.size() ||
      null_mask.type() != CV_8U) {
    return out;
  }
  const auto usable = [&](int r, int c) {
    return null_mask.at<uchar>(r, c) != 0 && std::isfinite(surface.at<float>(r, c));
  };
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  for (int r = 0; r < surface.rows; ++r) {
    for (int c = 0; c < surface.cols; ++c) {
      if (!usable(r, c)) continue;
      const double v = surface.at<float>(r, c);
      sum += v;
      sum_sq += v * v;
      ++n;
    }
  }
  out.samples = n;
  if (n < 2) return out;
  out.mean = sum / n;
  const double variance = std::max(0.0, sum_sq / n - out.mean * out.mean) * n / (n - 1.0);
  out.stddev = std::sqrt(variance);
  double dx = 0.0, dy = 0.0;
  int nx = 0, ny = 0;
  for (int r = 0; r < surface.rows; ++r) {
    for (int c = 0; c < surface.cols; ++c) {
      if (!usable(r, c)) continue;
      const double v = surface.at<float>(r, c);
      if (c + 1 < surface.cols && usable(r, c + 1)) {
        dx += std::pow(surface.at<float>(r, c + 1) - v, 2);
        ++nx;
      }
      if (r + 1 < surface.rows && usable(r + 1, c)) {
        dy += std::pow(surface.at<float>(r + 1, c) - v, 2);
        ++ny;
      }
    }
  }
  if (variance > 0.0 && nx > 0 && ny > 0) {
    out.lambda_x = dx / nx / variance;
    out.lambda_y = dy / ny / variance;
  }
  if (block_px > 0) {
    for (int r0 = 0; r0 < surface.rows; r0 += block_px) {
      for (int c0 = 0; c0 < surface.cols; c0 += block_px) {
        double bs = 0.0, bss = 0.0;
        int bn = 0;
        for (int r = r0; r < std::min(r0 + block_px, surface.rows); ++r) {
          for (int c = c0; c < std::min(c0 + block_px, surface.cols); ++c) {
            if (!usable(r, c)) continue;
            const double v = surface.at<float>(r, c);
            bs += v;
            bss += v * v;
            ++bn;
          }
        }
        if (2 * bn < block_px * block_px) continue;
        const double bv = std::max(0.0, bss / bn - (bs / bn) * (bs / bn)) * bn / (bn - 1.0);
        out.stddev = std::max(out.stddev, std::sqrt(bv));
      }
    }
  }
  return out;
}

PeakSignificance SignificanceOfPeak(double peak, const SurfaceNull& null, double width,
                                    double height, int warps) {
  PeakSignificance out;
  if (!null.valid() || !std::isfinite(peak)) return out;
  out.z = (peak - null.mean) / null.stddev;
  if (!(out.z > 0.0)) return out;
  const double z = out.z;
  const double g = std::exp(-0.5 * z * z);
  const double tail = 0.5 * std::erfc(z / std::numbers::sqrt2);
  const double two_pi = 2.0 * std::numbers::pi;
  const double sx = std::sqrt(null.lambda_x), sy = std::sqrt(null.lambda_y);
  const double euler =
      tail + (std::max(width, 1.0) * sx + std::max(height, 1.0) * sy) * g / two_pi +
      std::max(width, 1.0) * std::max(height, 1.0) * sx * sy * z * g / std::pow(two_pi, 1.5);
  out.expected_chance_peaks = std::max(warps, 1) * euler;
  out.false_match_probability = -std::expm1(-out.expected_chance_peaks);
  return out;
}

}  // namespace areomap
