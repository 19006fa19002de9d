#include "areomap/registration/masked_ncc.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <sstream>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_group.h>
#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/numbers.h"
#include "real_fft.h"

namespace areomap {
namespace internal {

// One image restricted to the pixels that take part, as the FFT and the naive sum use it:
// values centred on the mean of the valid pixels (NCC does not change, cancellation in the
// variance terms does) and zero where invalid, their squares, and validity as 0/1. A template
// prepared for reuse (PreparedTemplate) also keeps the integral images of the three, which the
// sums over an all-valid fixed crop read.
struct PreparedImage {
  cv::Mat value;     // CV_64F, centred, 0 where invalid.
  cv::Mat value_sq;  // CV_64F, value^2.
  cv::Mat valid;     // CV_64F, 1 where valid, 0 elsewhere.
  double energy = 0.0;
  int valid_count = 0;
  cv::Mat integral_valid, integral_value, integral_value_sq;  // CV_64F; empty unless reused.
};

}  // namespace internal

namespace {

using internal::PreparedImage;

constexpr double kInf = std::numeric_limits<double>::infinity();

// Sums of squared deviations below this fraction of the image's energy are FFT round-off
// (double-precision FFT error is ~1e-13 of the energy at the sizes used here, single-precision
// ~1e-6).
constexpr double kRelativeVarianceFloor = 1e-10;
constexpr double kRelativeVarianceFloorSingle = 1e-5;

[[noreturn]] void ThrowField(const std::string& field, double value, const std::string& rule) {
  std::ostringstream msg;
  msg << field << " = " << value << " is invalid: expected " << rule;
  throw Error(msg.str());
}

void CheckImage(const cv::Mat& image, const std::string& name) {
  if (image.empty()) {
    throw Error("masked NCC: the " + name + " image is empty; expected a CV_32FC1 image");
  }
  if (image.type() != CV_32FC1) {
    throw Error("masked NCC: the " + name + " image has type " + cv::typeToString(image.type()) +
                "; expected CV_32FC1");
  }
}

void CheckMask(const cv::Mat& mask, const cv::Mat& image, const std::string& name) {
  if (mask.empty()) return;
  if (mask.type() != CV_8UC1 || mask.size() != image.size()) {
    std::ostringstream msg;
    msg << "masked NCC: the " << name << " mask is " << mask.rows << "x" << mask.cols << " "
        << cv::typeToString(mask.type()) << "; expected an empty Mat or CV_8UC1 of the " << name
        << " image's size " << image.rows << "x" << image.cols;
    throw Error(msg.str());
  }
}

PreparedImage PrepareImage(const cv::Mat& image, const cv::Mat& mask, const cv::Rect& roi) {
  PreparedImage out;
  const cv::Mat in = image(roi);
  // Valid: finite (|v| < inf is false for NaN too) and unmasked. OpenCV's vectorised array
  // operations: this runs for every correlation, often on more pixels than shifts.
  cv::Mat valid;
  cv::compare(cv::abs(in), std::numeric_limits<float>::infinity(), valid, cv::CMP_LT);
  if (!mask.empty()) cv::bitwise_and(valid, mask(roi) != 0, valid);
  out.valid_count = cv::countNonZero(valid);
  in.convertTo(out.value, CV_64F);
  const double mean = out.valid_count > 0 ? cv::mean(out.value, valid)[0] : 0.0;
  out.value -= mean;
  out.value.setTo(0.0, valid == 0);
  valid.convertTo(out.valid, CV_64F, 1.0 / 255.0);
  cv::multiply(out.value, out.value, out.value_sq);
  out.energy = cv::sum(out.value_sq)[0];
  return out;
}

// Everything both implementations share: the inputs checked and prepared, the shifts to
// compute, and the thresholds.
struct Problem {
  PreparedImage fixed;  // The fixed image cropped to the pixels the shifts can reach.
  std::shared_ptr<const PreparedImage> moving;  // The whole template.
  int crop_x = 0;                               // Crop origin in the fixed image [px].
  int crop_y = 0;
  int shift_x0 = 0;  // Shifts to compute [px].
  int shift_y0 = 0;
  int rows = 0;
  int cols = 0;
  double min_overlap = 0.0;
  double min_sq_dev_per_pixel = 0.0;  // min_stddev^2.
  double fixed_floor = 0.0;           // Round-off floors on the sums of squared deviations.
  double moving_floor = 0.0;
  bool single_precision_fft = false;  // The FFT route's transforms in single precision.
};

// The template prepared (PrepareImage over all of it), after its checks; with `for_reuse` also
// the integral images of its three quantities.
std::shared_ptr<const PreparedImage> PrepareTemplate(const cv::Mat& moving,
                                                     const cv::Mat& moving_mask,
                                                     bool for_reuse = false) {
  CheckImage(moving, "moving");
  CheckMask(moving_mask, moving, "moving");
  auto prepared = std::make_shared<PreparedImage>(
      PrepareImage(moving, moving_mask, cv::Rect(0, 0, moving.cols, moving.rows)));
  if (for_reuse) {
    cv::integral(prepared->valid, prepared->integral_valid, CV_64F);
    cv::integral(prepared->value, prepared->integral_value, CV_64F);
    cv::integral(prepared->value_sq, prepared->integral_value_sq, CV_64F);
  }
  return prepared;
}

Problem MakeProblem(const cv::Mat& fixed, const cv::Mat& fixed_mask,
                    std::shared_ptr<const PreparedImage> prepared,
                    const MaskedNccOptions& options) {
  options.Check();
  CheckImage(fixed, "fixed");
  CheckMask(fixed_mask, fixed, "fixed");
  const cv::Size moving = prepared->value.size();

  Problem p;
  p.moving = std::move(prepared);
  // Every shift at which the template overlaps the fixed image at all.
  int x0 = -(moving.width - 1);
  int x1 = fixed.cols - 1;
  int y0 = -(moving.height - 1);
  int y1 = fixed.rows - 1;
  if (options.search_window) {
    const ShiftWindow& w = *options.search_window;
    x0 = std::max(x0, w.min_shift_x);
    x1 = std::min(x1, w.max_shift_x);
    y0 = std::max(y0, w.min_shift_y);
    y1 = std::min(y1, w.max_shift_y);
  }
  if (x0 > x1 || y0 > y1) return p;  // rows = cols = 0: nothing to compute.
  p.shift_x0 = x0;
  p.shift_y0 = y0;
  p.cols = x1 - x0 + 1;
  p.rows = y1 - y0 + 1;
  // Fixed pixels the template can cover at these shifts.
  p.crop_x = std::max(0, x0);
  p.crop_y = std::max(0, y0);
  const int crop_x1 = std::min(fixed.cols - 1, x1 + moving.width - 1);
  const int crop_y1 = std::min(fixed.rows - 1, y1 + moving.height - 1);
  const cv::Rect crop(p.crop_x, p.crop_y, crop_x1 - p.crop_x + 1, crop_y1 - p.crop_y + 1);

  p.fixed = PrepareImage(fixed, fixed_mask, crop);
  p.min_overlap = std::max(static_cast<double>(options.min_overlap_pixels),
                           std::ceil(options.min_overlap_fraction * p.moving->valid_count));
  p.min_sq_dev_per_pixel = options.min_stddev * options.min_stddev;
  p.single_precision_fft = options.fft_precision == FftPrecision::kSingle;
  // Single-precision transforms leave more round-off in the sums: a higher floor (where direct
  // sums end up used, a flat overlap is still far below it).
  const double floor =
      p.single_precision_fft ? kRelativeVarianceFloorSingle : kRelativeVarianceFloor;
  p.fixed_floor = floor * p.fixed.energy;
  p.moving_floor = floor * p.moving->energy;
  return p;
}

// The NCC from the six sums over the overlap (n pairs); NaN where undefined.
float Score(double n, double sum_f, double sum_m, double sum_ff, double sum_mm, double sum_fm,
            const Problem& p) {
  if (n < p.min_overlap) return std::numeric_limits<float>::quiet_NaN();
  const double sq_dev_f = sum_ff - sum_f * sum_f / n;
  const double sq_dev_m = sum_mm - sum_m * sum_m / n;
  const double min_sq_dev = n * p.min_sq_dev_per_pixel;
  if (sq_dev_f <= std::max(min_sq_dev, p.fixed_floor) ||
      sq_dev_m <= std::max(min_sq_dev, p.moving_floor)) {
    return std::numeric_limits<float>::quiet_NaN();
  }
  const double ncc = (sum_fm - sum_f * sum_m / n) / std::sqrt(sq_dev_f * sq_dev_m);
  return static_cast<float>(std::clamp(ncc, -1.0, 1.0));
}

MaskedNccSurface EmptySurface(const Problem& p) {
  MaskedNccSurface s;
  s.ncc.create(p.rows, p.cols, CV_32F);
  s.overlap.create(p.rows, p.cols, CV_32S);
  s.shift_x0 = p.shift_x0;
  s.shift_y0 = p.shift_y0;
  return s;
}

// Where the fixed crop sits in the FFT route's padded buffers: at offset o = -(first shift
// relative to the crop) >= 0, the template at 0, so that circular correlation index s is
// surface index s.
cv::Point FixedOffset(const Problem& p) {
  return cv::Point(p.crop_x - p.shift_x0, p.crop_y - p.shift_y0);
}

// The transform length FFTW (FFTW_ESTIMATE plans) runs fastest at or above `n`: the smallest
// 2^a, 3 x 2^a or 5 x 2^a. Longer than cv::getOptimalDFTSize's 2^a 3^b 5^c by 9 % on average, but
// FFTW's estimated plans for lengths with several odd factors (125, 216, 225) take 1.5-2x longer
// per point (real 2-D transforms: 90 x 125 0.070 ms, 96 x 128 0.038 ms; 216 x 288 0.239 ms,
// 256 x 320 0.188 ms).
int FastFftLength(int n) {
  int best = 1;
  while (best < n) best *= 2;
  for (const int odd : {3, 5}) {
    int length = odd;
    while (length < n) length *= 2;
    best = std::min(best, length);
  }
  return best;
}

// The FFT route's padded size. An index x + s (template pixel x) past the buffer end P wraps to
// x + s - P; that must land in the zeros before the crop (< o), which needs P >= template +
// shifts - 1 - o; the crop must fit, P >= o + crop. For all shifts this is the usual crop +
// template - 1; for shifts where the template lies inside the image it is just the image size.
cv::Size PaddedSize(const Problem& p) {
  const cv::Size crop = p.fixed.value.size();
  const cv::Size tmpl = p.moving->value.size();
  const cv::Point o = FixedOffset(p);
  return cv::Size(FastFftLength(std::max(o.x + crop.width, tmpl.width + p.cols - 1 - o.x)),
                  FastFftLength(std::max(o.y + crop.height, tmpl.height + p.rows - 1 - o.y)));
}

// The correlation of a template quantity `src` with an all-valid fixed crop: its sum over the
// overlap rectangle at each shift, from its integral image (`integral` where the template keeps
// it, else made here).
void OverlapSums(const Problem& p, const cv::Mat& src, const cv::Mat& kept_integral, cv::Mat* out) {
  const cv::Size crop = p.fixed.value.size();
  const cv::Size tmpl = p.moving->value.size();
  cv::Mat integral = kept_integral;
  if (integral.empty()) cv::integral(src, integral, CV_64F);
  out->create(p.rows, p.cols, CV_64F);
  for (int r = 0; r < p.rows; ++r) {
    const int dy = p.shift_y0 + r - p.crop_y;  // Shift relative to the crop.
    const int i0 = std::max(0, -dy);
    const int i1 = std::min(tmpl.height, crop.height - dy);
    const double* top = integral.ptr<double>(i0);
    const double* bottom = integral.ptr<double>(i1);
    double* dst = out->ptr<double>(r);
    for (int c = 0; c < p.cols; ++c) {
      const int dx = p.shift_x0 + c - p.crop_x;
      const int j0 = std::max(0, -dx);
      const int j1 = std::min(tmpl.width, crop.width - dx);
      dst[c] = bottom[j1] - bottom[j0] - top[j1] + top[j0];
    }
  }
}

// The six sums over the overlap (Padfield's correlations), CV_64F: row r, column c holds the sum
// at shift (p.shift_x0 + c, p.shift_y0 + r) (rows past p.rows, if any, are not computed).
struct OverlapCorrelations {
  cv::Mat n, sum_f, sum_m, sum_ff, sum_mm, sum_fm;
};

// The six correlations by FFTs, run as parallel TBB tasks.
template <class Real>
OverlapCorrelations CorrelateByFft(const Problem& p) {
  const cv::Size crop = p.fixed.value.size();
  const cv::Point fixed_offset = FixedOffset(p);
  const cv::Size padded = PaddedSize(p);
  using RealSpectrum = internal::RealSpectrum<Real>;
  const auto forward = [&](const cv::Mat& src, cv::Point offset, RealSpectrum* spectrum) {
    *spectrum = RealSpectrum::Forward(src, offset, padded);
  };
  const auto correlate = [&](const RealSpectrum& a, const RealSpectrum& b, cv::Mat* out) {
    *out = internal::Correlate(a, b, p.rows);
  };
  // With no invalid pixel in the crop (the usual orbital image), the three correlations
  // with the fixed validity are sums of template quantities over the overlap rectangle:
  // integral images replace one forward and three inverse DFTs, exactly.
  const bool fixed_all_valid = p.fixed.valid_count == crop.area();

  RealSpectrum f_valid, f_value, f_sq, m_valid, m_value, m_sq;
  OverlapCorrelations s;
  tbb::task_group tasks;
  tasks.run([&] { forward(p.fixed.value, fixed_offset, &f_value); });
  tasks.run([&] { forward(p.fixed.value_sq, fixed_offset, &f_sq); });
  tasks.run([&] { forward(p.moving->valid, cv::Point(0, 0), &m_valid); });
  tasks.run([&] { forward(p.moving->value, cv::Point(0, 0), &m_value); });
  if (fixed_all_valid) {
    tasks.run([&] { OverlapSums(p, p.moving->valid, p.moving->integral_valid, &s.n); });
    tasks.run([&] { OverlapSums(p, p.moving->value, p.moving->integral_value, &s.sum_m); });
    tasks.run([&] { OverlapSums(p, p.moving->value_sq, p.moving->integral_value_sq, &s.sum_mm); });
  } else {
    tasks.run([&] { forward(p.fixed.valid, fixed_offset, &f_valid); });
    tasks.run([&] { forward(p.moving->value_sq, cv::Point(0, 0), &m_sq); });
  }
  tasks.wait();
  tasks.run([&] { correlate(f_value, m_valid, &s.sum_f); });
  tasks.run([&] { correlate(f_sq, m_valid, &s.sum_ff); });
  tasks.run([&] { correlate(f_value, m_value, &s.sum_fm); });
  if (!fixed_all_valid) {
    tasks.run([&] { correlate(f_valid, m_valid, &s.n); });
    tasks.run([&] { correlate(f_valid, m_value, &s.sum_m); });
    tasks.run([&] { correlate(f_valid, m_sq, &s.sum_mm); });
  }
  tasks.wait();
  return s;
}

// The surface by FFTs (MaskedNcc's header); `p` has at least one shift.
MaskedNccSurface FftSurface(const Problem& p) {
  MaskedNccSurface surface = EmptySurface(p);
  const OverlapCorrelations s =
      p.single_precision_fft ? CorrelateByFft<float>(p) : CorrelateByFft<double>(p);
  tbb::parallel_for(tbb::blocked_range<int>(0, p.rows), [&](const tbb::blocked_range<int>& range) {
    for (int r = range.begin(); r != range.end(); ++r) {
      const double* pn = s.n.ptr<double>(r);
      const double* pf = s.sum_f.ptr<double>(r);
      const double* pm = s.sum_m.ptr<double>(r);
      const double* pff = s.sum_ff.ptr<double>(r);
      const double* pmm = s.sum_mm.ptr<double>(r);
      const double* pfm = s.sum_fm.ptr<double>(r);
      float* out = surface.ncc.ptr<float>(r);
      std::int32_t* count = surface.overlap.ptr<std::int32_t>(r);
      for (int c = 0; c < p.cols; ++c) {
        const double pairs = std::round(pn[c]);  // An integer up to FFT round-off.
        count[c] = static_cast<std::int32_t>(pairs);
        out[c] = pairs > 0.0 ? Score(pairs, pf[c], pm[c], pff[c], pmm[c], pfm[c], p)
                             : std::numeric_limits<float>::quiet_NaN();
      }
    }
  });
  return surface;
}

// Direct summation when every pixel of the fixed crop is valid (the usual orbital image): the
// template's own sums over the overlap rectangle come from OverlapSums (as on the FFT route), and
// the three sums with fixed values are row dot products, which Eigen vectorises.
MaskedNccSurface DirectSurfaceOnValidFixed(const Problem& p) {
  MaskedNccSurface surface = EmptySurface(p);
  cv::Mat pairs, sums_m, sums_mm;
  OverlapSums(p, p.moving->valid, p.moving->integral_valid, &pairs);
  OverlapSums(p, p.moving->value, p.moving->integral_value, &sums_m);
  OverlapSums(p, p.moving->value_sq, p.moving->integral_value_sq, &sums_mm);
  const cv::Size crop = p.fixed.value.size();
  const cv::Size tmpl = p.moving->value.size();
  using Row = Eigen::Map<const Eigen::VectorXd>;
  tbb::parallel_for(tbb::blocked_range<int>(0, p.rows), [&](const tbb::blocked_range<int>& range) {
    for (int r = range.begin(); r != range.end(); ++r) {
      const int dy = p.shift_y0 + r - p.crop_y;  // Shift relative to the crop.
      const int i0 = std::max(0, -dy), i1 = std::min(tmpl.height, crop.height - dy);
      for (int c = 0; c < p.cols; ++c) {
        const int dx = p.shift_x0 + c - p.crop_x;
        const int j0 = std::max(0, -dx), length = std::min(tmpl.width, crop.width - dx) - j0;
        const double n = std::round(pairs.at<double>(r, c));
        double sum_f = 0.0, sum_ff = 0.0, sum_fm = 0.0;
        for (int i = i0; i < i1 && length > 0; ++i) {
          const Row f(p.fixed.value.ptr<double>(i + dy) + dx + j0, length);
          const Row ff(p.fixed.value_sq.ptr<double>(i + dy) + dx + j0, length);
          const Row valid(p.moving->valid.ptr<double>(i) + j0, length);
          const Row m(p.moving->value.ptr<double>(i) + j0, length);
          sum_f += valid.dot(f);
          sum_ff += valid.dot(ff);
          sum_fm += m.dot(f);
        }
        surface.overlap.at<std::int32_t>(r, c) = static_cast<std::int32_t>(n);
        surface.ncc.at<float>(r, c) = n > 0.0 ? Score(n, sum_f, sums_m.at<double>(r, c), sum_ff,
                                                      sums_mm.at<double>(r, c), sum_fm, p)
                                              : std::numeric_limits<float>::quiet_NaN();
      }
    }
  });
  return surface;
}

// The surface by direct summation over each shift; `p` has at least one shift.
MaskedNccSurface DirectSurface(const Problem& p) {
  if (p.fixed.valid_count == p.fixed.value.size().area()) return DirectSurfaceOnValidFixed(p);
  MaskedNccSurface surface = EmptySurface(p);

  const int crop_rows = p.fixed.value.rows;
  const int crop_cols = p.fixed.value.cols;
  const int tmpl_rows = p.moving->value.rows;
  const int tmpl_cols = p.moving->value.cols;
  tbb::parallel_for(tbb::blocked_range<int>(0, p.rows), [&](const tbb::blocked_range<int>& range) {
    for (int r = range.begin(); r != range.end(); ++r) {
      const int dy = p.shift_y0 + r - p.crop_y;  // Shift relative to the crop.
      const int i0 = std::max(0, -dy);
      const int i1 = std::min(tmpl_rows, crop_rows - dy);
      for (int c = 0; c < p.cols; ++c) {
        const int dx = p.shift_x0 + c - p.crop_x;
        const int j0 = std::max(0, -dx);
        const int j1 = std::min(tmpl_cols, crop_cols - dx);
        double n = 0.0, sum_f = 0.0, sum_m = 0.0, sum_ff = 0.0, sum_mm = 0.0, sum_fm = 0.0;
        for (int i = i0; i < i1; ++i) {
          const double* f_ok = p.fixed.valid.ptr<double>(i + dy) + dx;
          const double* f_val = p.fixed.value.ptr<double>(i + dy) + dx;
          const double* m_ok = p.moving->valid.ptr<double>(i);
          const double* m_val = p.moving->value.ptr<double>(i);
          for (int j = j0; j < j1; ++j) {
            if (f_ok[j] == 0.0 || m_ok[j] == 0.0) continue;
            n += 1.0;
            sum_f += f_val[j];
            sum_m += m_val[j];
            sum_ff += f_val[j] * f_val[j];
            sum_mm += m_val[j] * m_val[j];
            sum_fm += f_val[j] * m_val[j];
          }
        }
        surface.overlap.at<std::int32_t>(r, c) = static_cast<std::int32_t>(n);
        surface.ncc.at<float>(r, c) = n > 0.0 ? Score(n, sum_f, sum_m, sum_ff, sum_mm, sum_fm, p)
                                              : std::numeric_limits<float>::quiet_NaN();
      }
    }
  });
  return surface;
}

// Direct summation costs about kDirectNsPerPair per valid template pixel and shift, the FFT
// route about kFftNsPerPoint per padded point, per transform, times log2 of the padded size
// (both on two threads; the ratio is what matters): fitted to `areomap_bench
// --benchmark_filter=WindowBy` (32 and 128 px templates, windows of radius 1 to 8), where the
// two cross at a radius of about 4 px. Release, GCC 12; FFTW 3.3 and the vectorised direct sums
// made both routes faster by about the same factor, so the crossing stayed.
constexpr double kDirectNsPerPair = 1.6;
constexpr double kFftNsPerPoint = 0.8;

// The FFT route's cost for buffers of `padded` size: its transforms (FftSurface's count: 7 with
// an all-valid fixed crop, else 12).
double FftCostOfPadded(cv::Size padded, bool fixed_all_valid) {
  const double points = static_cast<double>(padded.area());
  const double transforms = fixed_all_valid ? 7.0 : 12.0;
  return kFftNsPerPoint * transforms * points * std::log2(points);
}

double FftCost(const Problem& p) {
  return FftCostOfPadded(PaddedSize(p), p.fixed.valid_count == p.fixed.value.size().area());
}

double DirectCost(const Problem& p) {
  return kDirectNsPerPair * static_cast<double>(p.rows) * p.cols * p.moving->valid_count;
}

}  // namespace

ShiftWindow ShiftWindow::Around(int x, int y, int radius) {
  if (radius < 0) ThrowField("ShiftWindow::Around radius", radius, ">= 0 [px]");
  return ShiftWindow{x - radius, x + radius, y - radius, y + radius};
}

void MaskedNccOptions::Check() const {
  if (min_overlap_pixels < 2) {
    ThrowField("MaskedNccOptions.min_overlap_pixels", min_overlap_pixels, ">= 2 [px]");
  }
  if (!(min_overlap_fraction >= 0.0 && min_overlap_fraction <= 1.0)) {
    ThrowField("MaskedNccOptions.min_overlap_fraction", min_overlap_fraction,
               "a fraction in [0, 1]");
  }
  if (!(std::isfinite(min_stddev) && min_stddev >= 0.0)) {
    ThrowField("MaskedNccOptions.min_stddev", min_stddev, "a finite value >= 0");
  }
  if (search_window) {
    const ShiftWindow& w = *search_window;
    if (w.min_shift_x > w.max_shift_x) {
      ThrowField("MaskedNccOptions.search_window.min_shift_x", w.min_shift_x,
                 "<= search_window.max_shift_x (" + std::to_string(w.max_shift_x) + ")");
    }
    if (w.min_shift_y > w.max_shift_y) {
      ThrowField("MaskedNccOptions.search_window.min_shift_y", w.min_shift_y,
                 "<= search_window.max_shift_y (" + std::to_string(w.max_shift_y) + ")");
    }
  }
}

PreparedTemplate::PreparedTemplate(const cv::Mat& moving, const cv::Mat& moving_mask)
    : prepared_(PrepareTemplate(moving, moving_mask, /*for_reuse=*/true)) {}

cv::Size PreparedTemplate::size() const { return prepared_->value.size(); }

bool DirectNccIsCheaper(const cv::Mat& fixed, const cv::Mat& fixed_mask, const cv::Mat& moving,
                        const cv::Mat& moving_mask, const MaskedNccOptions& options) {
  const Problem p = MakeProblem(fixed, fixed_mask, PrepareTemplate(moving, moving_mask), options);
  return p.rows > 0 && DirectCost(p) < FftCost(p);
}

double FftNccCostNs(cv::Size moving, const ShiftWindow& shifts) {
  const int cols = shifts.max_shift_x - shifts.min_shift_x + 1;
  const int rows = shifts.max_shift_y - shifts.min_shift_y + 1;
  if (moving.area() <= 0 || cols <= 0 || rows <= 0) return 0.0;
  const cv::Size padded(FastFftLength(moving.width + cols - 1),
                        FastFftLength(moving.height + rows - 1));
  return FftCostOfPadded(padded, /*fixed_all_valid=*/true);
}

namespace {

MaskedNccSurface SurfaceOf(const Problem& p, const MaskedNccOptions& options) {
  if (p.rows == 0) return EmptySurface(p);
  switch (options.method) {
    case NccMethod::kFft:
      return FftSurface(p);
    case NccMethod::kDirect:
      return DirectSurface(p);
    case NccMethod::kAuto:
      break;
  }
  return DirectCost(p) < FftCost(p) ? DirectSurface(p) : FftSurface(p);
}

}  // namespace

MaskedNccSurface MaskedNcc(const cv::Mat& fixed, const cv::Mat& fixed_mask, const cv::Mat& moving,
                           const cv::Mat& moving_mask, const MaskedNccOptions& options) {
  return SurfaceOf(MakeProblem(fixed, fixed_mask, PrepareTemplate(moving, moving_mask), options),
                   options);
}

MaskedNccSurface MaskedNcc(const cv::Mat& fixed, const cv::Mat& fixed_mask,
                           const PreparedTemplate& moving, const MaskedNccOptions& options) {
  return SurfaceOf(MakeProblem(fixed, fixed_mask, moving.prepared_, options), options);
}

MaskedNccSurface MaskedNccNaive(const cv::Mat& fixed, const cv::Mat& fixed_mask,
                                const cv::Mat& moving, const cv::Mat& moving_mask,
                                const MaskedNccOptions& options) {
  MaskedNccOptions direct = options;
  direct.method = NccMethod::kDirect;
  return MaskedNcc(fixed, fixed_mask, moving, moving_mask, direct);
}

void PeakOptions::Check() const {
  if (!(std::isfinite(exclusion_radius) && exclusion_radius >= 0.0)) {
    ThrowField("PeakOptions.exclusion_radius", exclusion_radius, "a finite value >= 0 [px]");
  }
  if (!(min_peak >= -1.0 && min_peak <= 1.0)) {
    ThrowField("PeakOptions.min_peak", min_peak, "an NCC value in [-1, 1]");
  }
  if (!(min_peak_ratio >= 1.0)) {
    ThrowField("PeakOptions.min_peak_ratio", min_peak_ratio, "a ratio >= 1");
  }
  if (!(std::isfinite(min_sharpness) && min_sharpness >= 0.0)) {
    ThrowField("PeakOptions.min_sharpness", min_sharpness, "a finite NCC drop >= 0");
  }
}

namespace {

// Value at (r, c) of the surface, NaN outside it.
double At(const cv::Mat& ncc, int r, int c) {
  if (r < 0 || c < 0 || r >= ncc.rows || c >= ncc.cols) return kNaN;
  return ncc.at<float>(r, c);
}

// Vertex of the parabola through (-1, left), (0, centre), (1, right), limited to +-0.5;
// nullopt-like NaN if it cannot be fitted (missing neighbour, not a maximum).
double ParabolaOffset(double left, double centre, double right) {
  const double curvature = left - 2.0 * centre + right;
  if (!std::isfinite(left) || !std::isfinite(right) || !(curvature < 0.0)) return kNaN;
  return std::clamp((left - right) / (2.0 * curvature), -0.5, 0.5);
}

bool IsLocalMax(const cv::Mat& ncc, int r, int c, float value) {
  for (int dr = -1; dr <= 1; ++dr) {
    for (int dc = -1; dc <= 1; ++dc) {
      if (dr == 0 && dc == 0) continue;
      const double v = At(ncc, r + dr, c + dc);
      if (std::isfinite(v) && v > value) return false;
    }
  }
  return true;
}

void RefineSubpixel(const cv::Mat& ncc, int r, int c, SubpixelFit fit, NccPeak* peak) {
  double v[3][3];
  bool all_finite = true;
  for (int dr = -1; dr <= 1; ++dr) {
    for (int dc = -1; dc <= 1; ++dc) {
      v[dr + 1][dc + 1] = At(ncc, r + dr, c + dc);
      all_finite = all_finite && std::isfinite(v[dr + 1][dc + 1]);
    }
  }
  double offset_x = kNaN;
  double offset_y = kNaN;
  if (fit == SubpixelFit::kQuadratic2d && all_finite) {
    // Taylor expansion at the centre from central differences: gradient g, Hessian H; the
    // vertex is -H^-1 g when H is negative definite.
    const double gx = 0.5 * (v[1][2] - v[1][0]);
    const double gy = 0.5 * (v[2][1] - v[0][1]);
    const double hxx = v[1][2] - 2.0 * v[1][1] + v[1][0];
    const double hyy = v[2][1] - 2.0 * v[1][1] + v[0][1];
    const double hxy = 0.25 * (v[2][2] - v[2][0] - v[0][2] + v[0][0]);
    const double det = hxx * hyy - hxy * hxy;
    if (hxx < 0.0 && det > 0.0) {
      const double ox = -(hyy * gx - hxy * gy) / det;
      const double oy = -(hxx * gy - hxy * gx) / det;
      if (std::abs(ox) <= 1.0 && std::abs(oy) <= 1.0) {
        offset_x = std::clamp(ox, -0.5, 0.5);
        offset_y = std::clamp(oy, -0.5, 0.5);
      }
    }
  }
  if (!std::isfinite(offset_x) || !std::isfinite(offset_y)) {
    offset_x = ParabolaOffset(v[1][0], v[1][1], v[1][2]);
    offset_y = ParabolaOffset(v[0][1], v[1][1], v[2][1]);
  }
  peak->subpixel_refined = std::isfinite(offset_x) || std::isfinite(offset_y);
  peak->subpixel_x = peak->shift_x + (std::isfinite(offset_x) ? offset_x : 0.0);
  peak->subpixel_y = peak->shift_y + (std::isfinite(offset_y) ? offset_y : 0.0);
}

// The best finite score of a surface; the first in row-major order on ties, for determinism.
// r = c = -1 when no score is finite.
struct SurfaceMax {
  int r = -1;
  int c = -1;
  float value = -std::numeric_limits<float>::infinity();
};

SurfaceMax HighestScore(const cv::Mat& ncc) {
  SurfaceMax best;
  for (int r = 0; r < ncc.rows; ++r) {
    const float* row = ncc.ptr<float>(r);
    for (int c = 0; c < ncc.cols; ++c) {
      if (std::isfinite(row[c]) && row[c] > best.value) {
        best.value = row[c];
        best.r = r;
        best.c = c;
      }
    }
  }
  return best;
}

// Mean drop from `value` at (r, c) to its finite 8 neighbours; 0 without one.
double Sharpness(const cv::Mat& ncc, int r, int c, double value) {
  double drop_sum = 0.0;
  int drop_count = 0;
  for (int dr = -1; dr <= 1; ++dr) {
    for (int dc = -1; dc <= 1; ++dc) {
      const double v = At(ncc, r + dr, c + dc);
      if ((dr != 0 || dc != 0) && std::isfinite(v)) {
        drop_sum += value - v;
        ++drop_count;
      }
    }
  }
  return drop_count > 0 ? drop_sum / drop_count : 0.0;
}

// Runner-up: the highest local maximum farther than `exclusion_radius` from the best score at
// (best_r, best_c); sets the peak's second-peak fields, ratio and difference.
void FindRunnerUp(const MaskedNccSurface& surface, int best_r, int best_c, double exclusion_radius,
                  NccPeak* peak) {
  const cv::Mat& ncc = surface.ncc;
  const double radius_sq = exclusion_radius * exclusion_radius;
  float second = -std::numeric_limits<float>::infinity();
  for (int r = 0; r < ncc.rows; ++r) {
    const float* row = ncc.ptr<float>(r);
    const double dr = r - best_r;
    for (int c = 0; c < ncc.cols; ++c) {
      if (!std::isfinite(row[c]) || row[c] <= second) continue;
      const double dc = c - best_c;
      if (dr * dr + dc * dc <= radius_sq || !IsLocalMax(ncc, r, c, row[c])) continue;
      second = row[c];
      peak->has_second = true;
      peak->second_x = surface.shift_x0 + c;
      peak->second_y = surface.shift_y0 + r;
    }
  }
  if (peak->has_second) {
    peak->second_value = second;
    peak->peak_difference = peak->value - peak->second_value;
    peak->peak_ratio = peak->second_value > 0.0 ? peak->value / peak->second_value : kInf;
  } else {
    peak->peak_difference = kInf;
    peak->peak_ratio = kInf;
  }
}

// Which PeakOptions thresholds `peak` fails, "; "-separated; "" when it passes them all.
std::string WhyNotConfident(const NccPeak& peak, const PeakOptions& options) {
  std::ostringstream why;
  auto fail = [&why](const std::string& text) { why << (why.tellp() > 0 ? "; " : "") << text; };
  if (peak.value < options.min_peak) {
    fail("peak NCC " + std::to_string(peak.value) + " < min_peak " +
         std::to_string(options.min_peak));
  }
  if (peak.peak_ratio < options.min_peak_ratio) {
    fail("peak/second ratio " + std::to_string(peak.peak_ratio) + " < min_peak_ratio " +
         std::to_string(options.min_peak_ratio));
  }
  if (peak.sharpness < options.min_sharpness) {
    fail("sharpness " + std::to_string(peak.sharpness) + " < min_sharpness " +
         std::to_string(options.min_sharpness));
  }
  if (options.reject_border_peaks && peak.on_border) {
    fail("peak on the edge of the surface (the maximum may lie outside the search window)");
  }
  return why.str();
}

}  // namespace

NccPeak FindPeak(const MaskedNccSurface& surface, const PeakOptions& options) {
  options.Check();
  NccPeak peak;
  const cv::Mat& ncc = surface.ncc;
  if (surface.empty()) {
    peak.reason = "empty correlation surface (the search window misses the fixed image)";
    return peak;
  }
  CV_Assert(ncc.type() == CV_32FC1 && surface.overlap.type() == CV_32SC1 &&
            surface.overlap.size() == ncc.size());

  const SurfaceMax best = HighestScore(ncc);
  if (best.r < 0) {
    peak.reason = "no finite NCC score (too little overlap or texture at every shift)";
    return peak;
  }
  const int best_r = best.r, best_c = best.c;
  peak.found = true;
  peak.value = best.value;
  peak.shift_x = surface.shift_x0 + best_c;
  peak.shift_y = surface.shift_y0 + best_r;
  peak.overlap = surface.overlap.at<std::int32_t>(best_r, best_c);
  peak.on_border = best_r == 0 || best_c == 0 || best_r == ncc.rows - 1 || best_c == ncc.cols - 1;
  peak.sharpness = Sharpness(ncc, best_r, best_c, peak.value);
  RefineSubpixel(ncc, best_r, best_c, options.subpixel_fit, &peak);
  FindRunnerUp(surface, best_r, best_c, options.exclusion_radius, &peak);
  peak.reason = WhyNotConfident(peak, options);
  peak.confident = peak.reason.empty();
  return peak;
}

std::string NccPeak::BriefReport() const {
  std::ostringstream out;
  if (!found) {
    out << "no match: " << reason;
    return out.str();
  }
  out.setf(std::ios::fixed);
  out.precision(2);
  out << "shift (" << subpixel_x << ", " << subpixel_y << ") px";
  out.precision(3);
  out << ", NCC " << value << ", overlap " << overlap << " px";
  if (has_second) {
    out << ", second " << second_value << " (ratio " << peak_ratio << ")";
  } else {
    out << ", no second peak";
  }
  out << ", sharpness " << sharpness << ", ";
  out << (confident ? "confident" : "not confident: " + reason);
  return out.str();
}

}  // namespace areomap
