#include "chance_level.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include "high_pass.h"

namespace areomap::internal {
namespace {

// The null's spread is its largest over blocks of this many shifts a side (MeasureSurfaceNull).
constexpr int kNullBlock = 24;

// The null's statistics (mean, spread, smoothness over thousands of shifts) do not need the
// surfaces to better than ~1e-4: single-precision transforms, about 1.5x faster.
constexpr FftPrecision kNullPrecision = FftPrecision::kSingle;

// The NCC surface of `t` over `shifts` on `fixed`, its shifts in `fixed`'s frame; empty if they
// reach no pixel.
MaskedNccSurface SurfaceOver(const HighPassedImage& fixed, const MaskedImage& t,
                             const ShiftWindow& shifts, double min_overlap_fraction) {
  ShiftWindow local;
  const MaskedImage crop = fixed.Reach(shifts, t.image.size(), &local);
  if (crop.image.empty()) return {};
  MaskedNccOptions options;
  options.min_overlap_fraction = min_overlap_fraction;
  options.search_window = local;
  options.fft_precision = kNullPrecision;
  MaskedNccSurface s = MaskedNcc(crop.image, crop.mask, t.image, t.mask, options);
  s.shift_x0 += shifts.min_shift_x - local.min_shift_x;
  s.shift_y0 += shifts.min_shift_y - local.min_shift_y;
  return s;
}

}  // namespace

double PeakNear(const HighPassedImage& hp_fixed, const MaskedImage& hp_t, cv::Point shift,
                double min_overlap_fraction) {
  const MaskedNccSurface s =
      SurfaceOver(hp_fixed, hp_t, ShiftWindow::Around(shift.x, shift.y, 1), min_overlap_fraction);
  double best = std::numeric_limits<double>::quiet_NaN();
  for (auto it = s.ncc.begin<float>(); it != s.ncc.end<float>(); ++it) {
    if (std::isfinite(*it) && !(best >= *it)) best = *it;
  }
  return best;
}

SurfaceNull NullWindowTest(const OrbitalImage& orbital, const MaskedImage& t, int cx, int cy,
                           int radius, double exclusion_px, int wanted, double min_overlap_fraction,
                           OrbitalMatch& m) {
  const int side = 2 * radius + 1;
  // Tile (i, j) is centred on (cx + i side, cy + j side); with max(|i|, |j|) = k its nearest
  // shift is (k - 1) side + 1 away from the window's farthest.
  const int k_min = 2 + static_cast<int>(std::floor(exclusion_px / side));
  int k_max = k_min;
  const auto count = [&](int k) {
    return (2 * k + 1) * (2 * k + 1) - (2 * k_min - 1) * (2 * k_min - 1);
  };
  while (count(k_max) < wanted) ++k_max;
  const int reach = k_max * side + radius;
  PixelWindow window{cx - reach, cy - reach, t.image.cols + 2 * reach, t.image.rows + 2 * reach};
  const cv::Mat patch = orbital.ReadWindow(window);
  m.null_windows = 0;
  m.null_reaching = 0;
  m.null_highest = std::numeric_limits<double>::quiet_NaN();
  if (patch.empty()) return {};
  MaskedNccOptions options;
  options.min_overlap_fraction = min_overlap_fraction;
  options.search_window = ShiftWindow::Around(cx - window.col0, cy - window.row0, reach);
  const MaskedNccSurface surface = MaskedNcc(patch, {}, t.image, t.mask, options);
  const MaskedImage hp_patch = HighPass({patch, {}}, kHighPassSigmaPx);
  const MaskedImage hp_t = HighPass(t, kHighPassSigmaPx);
  MaskedNccOptions null_options = options;
  null_options.fft_precision = kNullPrecision;
  const MaskedNccSurface hp_surface =
      MaskedNcc(hp_patch.image, hp_patch.mask, hp_t.image, hp_t.mask, null_options);
  if (surface.empty()) return {};
  cv::Mat null_mask(surface.ncc.size(), CV_8U, cv::Scalar(0));
  for (int j = -k_max; j <= k_max; ++j) {
    for (int i = -k_max; i <= k_max; ++i) {
      if (std::max(std::abs(i), std::abs(j)) < k_min) continue;
      const int tx = cx + i * side - window.col0 - surface.shift_x0;
      const int ty = cy + j * side - window.row0 - surface.shift_y0;
      const cv::Rect tile = cv::Rect(tx - radius, ty - radius, side, side) &
                            cv::Rect(0, 0, surface.ncc.cols, surface.ncc.rows);
      double best = -2.0;
      for (int r = tile.y; r < tile.y + tile.height; ++r) {
        for (int c = tile.x; c < tile.x + tile.width; ++c) {
          const float v = surface.ncc.at<float>(r, c);
          if (std::isfinite(v)) best = std::max(best, static_cast<double>(v));
        }
      }
      if (best < -1.5) continue;
      null_mask(tile).setTo(255);
      ++m.null_windows;
      if (best >= m.correlation) ++m.null_reaching;
      if (!(best <= m.null_highest)) m.null_highest = best;
    }
  }
  if (m.null_windows < (wanted + 1) / 2 || hp_surface.ncc.size() != surface.ncc.size()) return {};
  return MeasureSurfaceNull(hp_surface.ncc, null_mask, kNullBlock);
}

// Where a match's own peak spreads on a surface: the template's autocorrelation at least this
// (a perfect match's surface is the autocorrelation; an imperfect one's, that scaled by its CC).
constexpr double kPeakLobe = 0.2;

MaskedNccSurface Autocorrelation(const MaskedImage& t, int rows, int cols) {
  MaskedNccOptions self;
  self.min_overlap_fraction = 0.25;
  self.fft_precision = kNullPrecision;
  self.search_window = ShiftWindow{-cols, cols, -rows, rows};
  return MaskedNcc(t.image, t.mask, t.image, t.mask, self);
}

// Tiles of this many shifts a side sample a large window's full-resolution surface.
constexpr int kNullTile = 48;

bool NullReachesAllOf(cv::Size window, cv::Size templ) {
  const int margin = GaussianReachPx(kHighPassSigmaPx);
  const double tile_reach = static_cast<double>(templ.width + kNullTile + 2 * margin) *
                            (templ.height + kNullTile + 2 * margin);
  return static_cast<double>(window.area()) <= 4.0 * tile_reach;
}

SurfaceNull WindowTilesNull(const HighPassedImage& hp_fixed, const MaskedImage& hp_t,
                            const ShiftWindow& search, cv::Point peak,
                            const MaskedImage& coarse_template, cv::Size acf_extent, int unit,
                            double exclusion_px, double min_overlap_fraction) {
  // Tiles go where the template lies on the image (a clipped window's corners do not).
  ShiftWindow window = search;
  const ShiftWindow inside{std::max(window.min_shift_x, 0),
                           std::min(window.max_shift_x, hp_fixed.size().width - hp_t.image.cols),
                           std::max(window.min_shift_y, 0),
                           std::min(window.max_shift_y, hp_fixed.size().height - hp_t.image.rows)};
  if (inside.min_shift_x <= inside.max_shift_x && inside.min_shift_y <= inside.max_shift_y) {
    window = inside;
  }
  const int side = window.max_shift_x - window.min_shift_x + 1;
  const int height = window.max_shift_y - window.min_shift_y + 1;
  // A window under two tiles a side is one tile: all of it.
  const int n = std::min(side, height) >= 2 * kNullTile ? 2 : 1;
  const int tile_w = n == 1 ? side : kNullTile, tile_h = n == 1 ? height : kNullTile;
  cv::Mat all(height, side, CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  cv::Mat null_mask(height, side, CV_8U, cv::Scalar(0));
  MaskedNccSurface acf;
  const auto in_lobe = [&](int dx, int dy) {
    if (std::hypot(dx, dy) <= exclusion_px) return true;
    const int ac = static_cast<int>(std::lround(static_cast<double>(dx) / unit)) - acf.shift_x0;
    const int ar = static_cast<int>(std::lround(static_cast<double>(dy) / unit)) - acf.shift_y0;
    if (ar < 0 || ac < 0 || ar >= acf.ncc.rows || ac >= acf.ncc.cols) return false;
    return acf.ncc.at<float>(ar, ac) >= kPeakLobe;
  };
  const auto tile_at = [&](int k) {
    const double step = n > 1 ? 1.0 / (n - 1.0) : 0.0;
    const int x0 =
        window.min_shift_x + static_cast<int>(std::lround((k % n) * (side - tile_w) * step));
    const int y0 =
        window.min_shift_y + static_cast<int>(std::lround((k / n) * (height - tile_h) * step));
    return ShiftWindow{x0, x0 + tile_w - 1, y0, y0 + tile_h - 1};
  };
  // Copies the shifts of `tile` that `s` holds into `all`, and marks those off the peak's lobe.
  const auto sample = [&](const MaskedNccSurface& s, const ShiftWindow& tile) {
    for (int sy = tile.min_shift_y; sy <= tile.max_shift_y; ++sy) {
      for (int sx = tile.min_shift_x; sx <= tile.max_shift_x; ++sx) {
        const int c = sx - s.shift_x0, r = sy - s.shift_y0;
        if (c < 0 || r < 0 || c >= s.ncc.cols || r >= s.ncc.rows) continue;
        const int px = sx - window.min_shift_x, py = sy - window.min_shift_y;
        all.at<float>(py, px) = s.ncc.at<float>(r, c);
        if (!in_lobe(sx - peak.x, sy - peak.y)) null_mask.at<uchar>(py, px) = 255;
      }
    }
  };
  // A small window's tiles reach nearly the same pixels: one surface over all of it costs less
  // than one per tile; the tiles' shifts are sampled either way. The surfaces are computed beside
  // the autocorrelation that marks the peak's lobe.
  const double tiles_cost = n * n * FftNccCostNs(hp_t.image.size(), tile_at(0));
  const bool one_surface = n > 1 && FftNccCostNs(hp_t.image.size(), window) < tiles_cost;
  std::vector<MaskedNccSurface> surfaces(one_surface ? 1 : n * n);
  tbb::parallel_invoke(
      [&] { acf = Autocorrelation(coarse_template, acf_extent.height, acf_extent.width); },
      [&] {
        tbb::parallel_for(0, static_cast<int>(surfaces.size()), [&](int k) {
          surfaces[k] =
              SurfaceOver(hp_fixed, hp_t, one_surface ? window : tile_at(k), min_overlap_fraction);
        });
      });
  for (int k = 0; k < n * n; ++k) sample(surfaces[one_surface ? 0 : k], tile_at(k));
  return MeasureSurfaceNull(all, null_mask, kNullBlock);
}

}  // namespace areomap::internal
