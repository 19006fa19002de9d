// Nodata-aware (masked) normalized cross-correlation in the Fourier domain, and analysis of
// the resulting correlation surface.
//
// This is the core of matching a rover orthophoto (which has holes: occlusions, areas out of
// stereo range, the rover's own shadow) onto an orbital image. The method is Padfield,
// "Masked object registration in the Fourier domain", IEEE TIP 21(5), 2012: the NCC over
// the overlap of valid pixels is assembled, for every integer shift at once, from six
// correlations (overlap count, two sums, two sums of squares, the cross term) computed with
// FFTs. scikit-image (`phase_cross_correlation` with `reference_mask`) and ITK
// (MaskedFFTNormalizedCorrelationImageFilter) implement the same method.
//
// Conventions (all functions in this header):
// - Images are single-channel CV_32F, in any intensity unit. Masks are CV_8U of the same size
//   as their image, nonzero = valid; an empty mask means "all pixels valid". A NaN or
//   infinite pixel is invalid whatever its mask says.
// - Pixel (r, c) is row r, column c; a shift (x, y) [px] places the template's top-left pixel
//   on fixed-image pixel (column x, row y), i.e. template pixel (i, j) is compared with fixed
//   pixel (i + y, j + x). Shifts may be negative (template hanging over the top/left edge).
// - Per-shift failures (too little overlap, a flat overlap) are NaN in the surface, never an
//   exception; bad arguments or options throw areomap::Error naming the argument or field.
//
// Speed and agreement against OpenCV's cv::matchTemplate: docs/benchmarks.md, "Masked NCC and
// orbital registration".
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

namespace areomap {

namespace internal {
struct PreparedImage;
}  // namespace internal

// An inclusive rectangle of integer shifts [px] (see the header comment for the convention).
struct ShiftWindow {
  int min_shift_x = 0;  // Smallest shift in x (columns) [px].
  int max_shift_x = 0;  // Largest shift in x (columns) [px], >= min_shift_x.
  int min_shift_y = 0;  // Smallest shift in y (rows) [px].
  int max_shift_y = 0;  // Largest shift in y (rows) [px], >= min_shift_y.

  // A window of +-radius [px] around a prior shift (x, y).
  static ShiftWindow Around(int x, int y, int radius);
};

// How MaskedNcc computes a surface: by FFTs, by direct summation over each shift, or by the one
// its cost model says is cheaper for the sizes at hand (as cv::matchTemplate picks between its
// DFT and direct paths). Both give the same surface to ~1e-6.
enum class NccMethod { kAuto, kFft, kDirect };

// The FFT route's transforms in double precision (surfaces within ~1e-6 of direct sums), or in
// single precision: about 1.5x faster, surfaces within ~1e-4, and overlaps flat to 1e-5 of the
// image's energy count as flat. For statistics over many shifts (a chance level), not for
// locating a peak. Direct sums are always in double precision.
enum class FftPrecision { kDouble, kSingle };

struct MaskedNccOptions {
  // Shifts whose overlap has fewer valid pixel pairs than
  // max(min_overlap_pixels, ceil(min_overlap_fraction * valid template pixels)) get NaN.
  int min_overlap_pixels = 16;        // Minimum overlap [px], >= 2.
  double min_overlap_fraction = 0.5;  // Minimum overlap [fraction of valid template px], [0, 1].
  // Shifts where either image's standard deviation over the overlap is at most this get NaN
  // (a flat patch has no defined correlation). A relative floor of 1e-10 of the image energy
  // also applies, to reject what is flat up to FFT round-off.
  double min_stddev = 1e-6;  // [image intensity units], >= 0.
  // When set, only these shifts are computed (a prior position limits the search); the fixed
  // image is cropped to the pixels they can reach, so a small window is also fast.
  std::optional<ShiftWindow> search_window;
  NccMethod method = NccMethod::kAuto;
  FftPrecision fft_precision = FftPrecision::kDouble;

  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

// The correlation surface: ncc(r, c) is the masked NCC, in [-1, 1], when the template's
// top-left pixel sits at fixed-image pixel (column c + shift_x0, row r + shift_y0); NaN
// where it is undefined (see MaskedNccOptions). overlap(r, c) is the number of valid pixel
// pairs at that shift.
//
// Without a search window the surface covers every shift at which the template overlaps the
// fixed image at all: shift_x0 = -(template cols - 1), shift_y0 = -(template rows - 1), and
// the size is (fixed rows + template rows - 1) x (fixed cols + template cols - 1). With a
// window, it covers the window clipped to those shifts; it is empty (0 x 0) if the window
// lies entirely outside them.
struct MaskedNccSurface {
  cv::Mat ncc;       // CV_32F, NaN where undefined.
  cv::Mat overlap;   // CV_32S, number of valid pixel pairs [px].
  int shift_x0 = 0;  // Shift in x [px] of column 0.
  int shift_y0 = 0;  // Shift in y [px] of row 0.

  bool empty() const { return ncc.empty(); }
};

// Masked NCC of `moving` (the template, e.g. the rover orthophoto) against `fixed` (e.g. the
// orbital image) for all shifts, or those of options.search_window. By direct summation where
// that costs less (options.method, DirectNccIsCheaper), else through FFTs (FFTW, double
// precision, padded to lengths 2^a, 3 x 2^a or 5 x 2^a, which FFTW's estimated plans transform
// fastest; run as parallel TBB tasks; the first use of a padded size in a process plans its
// transforms, about 1 ms): six correlations, or three plus integral images where the fixed image
// has no invalid pixel in reach. Agrees with MaskedNccNaive to ~1e-6 or better. Cost O(P log P)
// with P the padded size, per axis at most shifts + template - 1: fixed + template - 1 for all
// shifts, the fixed image's size for the shifts where the template lies inside it
// (cv::matchTemplate's). Throws areomap::Error if an image is empty or not CV_32FC1, a mask is
// not an empty Mat or CV_8UC1 of its image's size, or the options fail Check().
MaskedNccSurface MaskedNcc(const cv::Mat& fixed, const cv::Mat& fixed_mask, const cv::Mat& moving,
                           const cv::Mat& moving_mask, const MaskedNccOptions& options = {});

// A template prepared once for several MaskedNcc calls (the refinement of a match correlates one
// template in many small windows): its valid pixels, values centred on their mean, squares and
// their integral images. Cheap to copy (shared, immutable). Throws areomap::Error for a bad image
// or mask, as MaskedNcc does.
class PreparedTemplate {
 public:
  PreparedTemplate(const cv::Mat& moving, const cv::Mat& moving_mask);
  cv::Size size() const;

 private:
  friend MaskedNccSurface MaskedNcc(const cv::Mat& fixed, const cv::Mat& fixed_mask,
                                    const PreparedTemplate& moving,
                                    const MaskedNccOptions& options);
  std::shared_ptr<const internal::PreparedImage> prepared_;
};

// MaskedNcc of a prepared template: the same surface as with the template it was made from.
MaskedNccSurface MaskedNcc(const cv::Mat& fixed, const cv::Mat& fixed_mask,
                           const PreparedTemplate& moving, const MaskedNccOptions& options = {});

// Whether MaskedNcc's cost model (NccMethod::kAuto) picks direct summation for these inputs:
// the shifts times the valid template pixels against the FFT route's transforms of its padded
// size. Same arguments and errors as MaskedNcc; false when no shift is computed.
bool DirectNccIsCheaper(const cv::Mat& fixed, const cv::Mat& fixed_mask, const cv::Mat& moving,
                        const cv::Mat& moving_mask, const MaskedNccOptions& options = {});

// The cost model's estimate [ns] of MaskedNcc by FFTs over `shifts` for a template of size
// `moving` on a fixed image with no invalid pixel in their reach: for choosing how to cut a
// search (one window or several) before any image is cropped. 0 for an empty window.
double FftNccCostNs(cv::Size moving, const ShiftWindow& shifts);

// The same surface by direct summation over each shift: the reference the FFT version is
// tested and benchmarked against. Cost O(shifts x template pixels): only for small images or
// small search windows. Same arguments, conventions and errors as MaskedNcc.
MaskedNccSurface MaskedNccNaive(const cv::Mat& fixed, const cv::Mat& fixed_mask,
                                const cv::Mat& moving, const cv::Mat& moving_mask,
                                const MaskedNccOptions& options = {});

enum class SubpixelFit {
  kQuadratic2d,        // Full 2D quadratic (with cross term) through the 3x3 neighbourhood.
  kSeparableParabola,  // Independent 1D parabolas through the row and the column.
};

struct PeakOptions {
  // The second-best peak is the highest local maximum farther than this from the best one.
  double exclusion_radius = 3.0;  // [px], >= 0.
  double min_peak = 0.4;          // Confident only if the peak NCC is >= this, [-1, 1].
  double min_peak_ratio = 1.2;    // Confident only if peak / second peak >= this, >= 1.
  // Confident only if the mean drop to the 8 neighbours is >= this [NCC], >= 0.
  double min_sharpness = 0.0;
  // A peak on the edge of the surface (in practice: of a search window) may be the slope of a
  // maximum outside it; when true such a peak is never confident.
  bool reject_border_peaks = true;
  SubpixelFit subpixel_fit = SubpixelFit::kQuadratic2d;

  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

// The best match on a correlation surface and how much to trust it. Shifts follow the
// MaskedNccSurface convention (template top-left on fixed pixel (x, y)) [px].
struct NccPeak {
  bool found = false;      // The surface has at least one finite score.
  bool confident = false;  // All PeakOptions thresholds pass; otherwise `reason` says which failed.
  int shift_x = 0;         // Best integer shift [px].
  int shift_y = 0;
  // Refined shift [px]; equals the integer shift where no fit was possible.
  double subpixel_x = 0.0;
  double subpixel_y = 0.0;
  bool subpixel_refined = false;  // Whether a fit refined at least one axis.
  double value = 0.0;             // NCC at the best integer shift.
  int overlap = 0;                // Valid pixel pairs at the best shift [px].
  bool on_border = false;         // The best shift lies on the surface's edge.
  bool has_second = false;        // A second local maximum exists outside the exclusion radius.
  int second_x = 0;               // Its shift [px] (valid when has_second).
  int second_y = 0;
  double second_value = 0.0;     // Its NCC (valid when has_second).
  double peak_ratio = 0.0;       // value / second_value; +inf without a positive second peak.
  double peak_difference = 0.0;  // value - second_value; +inf without a second peak.
  double sharpness = 0.0;        // Mean of value - neighbour over the finite 8 neighbours [NCC].
  std::string reason;            // Why the peak is not confident; empty when it is.

  // One line: shift, value, ratio, sharpness, confidence.
  std::string BriefReport() const;
};

// Finds the best shift on `surface`, refines it to sub-pixel precision (the fit is limited to
// +-0.5 px per axis of the integer peak and skipped where a neighbour is NaN or off the
// surface), finds the runner-up peak and decides whether the match is confident. A
// low-confidence or empty result is reported as such (confident = false, with a reason),
// never as a match. Throws areomap::Error if the options fail Check().
NccPeak FindPeak(const MaskedNccSurface& surface, const PeakOptions& options = {});

}  // namespace areomap
