#include "areomap/registration/orbital_match.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <limits>
#include <numbers>
#include <sstream>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/registration/masked_ncc.h"
#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_pyramid.h"
#include "areomap/registration/part_consistency.h"
#include "chance_level.h"
#include "high_pass.h"

namespace areomap {
namespace {

using internal::Autocorrelation;
using internal::HighPass;
using internal::kHighPassSigmaPx;
using internal::NullWindowTest;
using internal::PeakNear;
using internal::WindowTilesNull;

void Report(const ProgressCallback& progress, double fraction, std::string_view stage) {
  if (progress && !progress(fraction, stage)) throw Error("orbital registration cancelled");
}

Eigen::Matrix2d SimilarityMatrix(double rotation, double scale) {
  // Counter-clockwise on a north-up map = clockwise in (column, row) pixel axes.
  const double c = std::cos(rotation), s = std::sin(rotation);
  Eigen::Matrix2d a;
  a << c, s, -s, c;
  return scale * a;
}

// The template warped by A about its centre: W(q) = T(A^-1 (q - c) + c).
MaskedImage WarpTemplate(const OrbitalTemplate& templ, double rotation, double scale) {
  MaskedImage out;
  if (rotation == 0.0 && scale == 1.0) {
    out.image = templ.image;
    out.mask = templ.mask;
    return out;
  }
  const Eigen::Matrix2d a = SimilarityMatrix(rotation, scale);
  const Eigen::Vector2d c((templ.image.cols - 1) / 2.0, (templ.image.rows - 1) / 2.0);
  const Eigen::Vector2d t = c - a * c;
  const cv::Mat m = (cv::Mat_<double>(2, 3) << a(0, 0), a(0, 1), t.x(), a(1, 0), a(1, 1), t.y());
  cv::Mat value(templ.image.size(), CV_32F, cv::Scalar(0.0f)), weight;
  templ.image.copyTo(value, templ.mask);
  templ.mask.convertTo(weight, CV_32F, 1.0 / 255.0);
  cv::Mat warped_value, warped_weight;
  cv::warpAffine(value, warped_value, m, value.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  cv::warpAffine(weight, warped_weight, m, value.size(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
  out.image.create(value.size(), CV_32F);
  out.mask.create(value.size(), CV_8U);
  for (int r = 0; r < value.rows; ++r) {
    for (int col = 0; col < value.cols; ++col) {
      const float w = warped_weight.at<float>(r, col);
      const bool ok = w >= 0.99f;
      out.image.at<float>(r, col) =
          ok ? warped_value.at<float>(r, col) / w : std::numeric_limits<float>::quiet_NaN();
      out.mask.at<uchar>(r, col) = ok ? 255 : 0;
    }
  }
  return out;
}

int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int CeilDiv(int a, int b) { return -FloorDiv(-a, b); }

// d SimilarityMatrix(rotation, 1) / d rotation at 0: how a turn moves a point about the centre.
const Eigen::Matrix2d kTurn = (Eigen::Matrix2d() << 0.0, 1.0, -1.0, 0.0).finished();

// Covariance of a correlation match after Forstner (1982): the residual noise variance times
// the inverse of the normal matrix of the template's gradients. Its parameters are the shift
// [px] and, with `with_rotation`, a turn about the template centre [rad], whose design column at
// pixel p is the gradient along kTurn (p - centre): a 2 x 2 or 3 x 3 matrix (NaN where the
// normal matrix is singular). The residual variance follows from the correlation coefficient
// rho of template T against the image, s_T^2 (1 - rho^2) / rho^2 (the regression residual in
// template units), and the sums count valid pixels whose neighbours are valid. Residuals
// between a rover orthophoto and an orbital image (shading, resampling) are correlated over
// about the low-pass footprint, which shrinks the number of independent samples by
// `correlation_area` pixels.
Eigen::MatrixXd MatchCovariance(const MaskedImage& t, double rho, double correlation_area,
                                bool with_rotation) {
  const int n_params = with_rotation ? 3 : 2;
  Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  const Eigen::Vector2d centre(t.image.cols / 2.0, t.image.rows / 2.0);
  for (int r = 1; r + 1 < t.image.rows; ++r) {
    for (int c = 1; c + 1 < t.image.cols; ++c) {
      const auto ok = [&](int rr, int cc) { return t.mask.at<uchar>(rr, cc) != 0; };
      if (!ok(r, c) || !ok(r, c - 1) || !ok(r, c + 1) || !ok(r - 1, c) || !ok(r + 1, c)) continue;
      const double v = t.image.at<float>(r, c);
      const Eigen::Vector2d g(0.5 * (t.image.at<float>(r, c + 1) - t.image.at<float>(r, c - 1)),
                              0.5 * (t.image.at<float>(r + 1, c) - t.image.at<float>(r - 1, c)));
      const Eigen::Vector2d p = Eigen::Vector2d(c + 0.5, r + 0.5) - centre;
      const Eigen::Vector3d design(g.x(), g.y(), g.dot(kTurn * p));
      normal.noalias() += design * design.transpose();
      sum += v;
      sum_sq += v * v;
      ++n;
    }
  }
  const Eigen::MatrixXd used = normal.topLeftCorner(n_params, n_params);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (n < 10 || rho <= 0.0 || used.determinant() <= 0.0) {
    return Eigen::MatrixXd::Constant(n_params, n_params, nan);
  }
  const double variance = std::max(0.0, sum_sq / n - (sum / n) * (sum / n));
  const double residual = variance * (1.0 - rho * rho) / (rho * rho);
  return residual * correlation_area * used.inverse();
}

// The shift's covariance with the rotation held (the Schur complement of a 3 x 3 match
// covariance, MatchCovariance; a 2 x 2 one as it is).
Eigen::Matrix2d ShiftWithRotationHeld(const Eigen::MatrixXd& match) {
  if (match.rows() == 2) return match;
  return match.topLeftCorner<2, 2>() -
         match.topRightCorner<2, 1>() * match.bottomLeftCorner<1, 2>() / match(2, 2);
}

// Where the template's texture pins the shift (OrbitalMatch::rotation_pivot_px), from a match
// covariance (MatchCovariance) of a template centred at `centre`: with the rotation, the shift's
// error is its error with the rotation held plus b x the rotation's error (b = cov(shift,
// rotation) / var(rotation): a template textured off its centre keeps that texture in place when
// it turns), so a turn error moves pixel u by kTurn (u - centre) + b = kTurn (u - pivot), pivot =
// centre + kTurn b. The centre itself for a 2 x 2 or singular covariance.
Eigen::Vector2d RotationPivot(const Eigen::MatrixXd& match, const Eigen::Vector2d& centre) {
  if (match.rows() == 2 || !std::isfinite(match(2, 2)) || match(2, 2) <= 0.0) return centre;
  return centre + kTurn * match.topRightCorner<2, 1>() / match(2, 2);
}

// The rover's covariance from a match covariance (MatchCovariance, 2 x 2 or 3 x 3): the shift's,
// and with the rotation its error times the rover's `lever_px` (kTurn (rover - pivot),
// RotationPivot). `rotation_floor` [rad] is added in quadrature to the rotation's own sigma only:
// the pivot stays what the data give.
Eigen::Matrix2d RoverCovariance(const Eigen::MatrixXd& match, const Eigen::Vector2d& lever_px,
                                double rotation_floor) {
  if (match.rows() == 2) return match;
  return ShiftWithRotationHeld(match) +
         (match(2, 2) + rotation_floor * rotation_floor) * lever_px * lever_px.transpose();
}

// How much the rotation's floor grows at peak correlation `rho` below `reference`
// (OrbitalMatchOptions::rotation_floor_correlation): (g(rho) / g(reference))^2 with g(r) =
// (1 - r^2) / r^2, the residual-to-signal variance ratio of Forstner's covariance; 1 at or
// above the reference (and for rho <= 0, where nothing was matched).
double LowCorrelationGrowth(double rho, double reference) {
  if (!(rho > 0.0) || rho >= reference) return 1.0;
  const auto g = [](double r) { return (1.0 - r * r) / (r * r); };
  return std::pow(g(rho) / g(reference), 2);
}

// The `count` highest local maxima (3 x 3, finite neighbours only) of a surface, at least
// `separation` [px] apart (greedy, highest first), as shifts.
std::vector<cv::Point> TopLocalMaxima(const MaskedNccSurface& surface, int count,
                                      double separation) {
  std::vector<std::pair<float, cv::Point>> maxima;
  const cv::Mat& s = surface.ncc;
  for (int r = 0; r < s.rows; ++r) {
    for (int c = 0; c < s.cols; ++c) {
      const float v = s.at<float>(r, c);
      if (!std::isfinite(v)) continue;
      bool is_max = true;
      for (int dr = -1; dr <= 1 && is_max; ++dr) {
        for (int dc = -1; dc <= 1; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if ((dr == 0 && dc == 0) || rr < 0 || cc < 0 || rr >= s.rows || cc >= s.cols) continue;
          if (s.at<float>(rr, cc) > v) {
            is_max = false;
            break;
          }
        }
      }
      if (is_max) maxima.emplace_back(v, cv::Point(c + surface.shift_x0, r + surface.shift_y0));
    }
  }
  std::sort(maxima.begin(), maxima.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<cv::Point> out;
  for (const auto& [value, p] : maxima) {
    bool far = true;
    for (const cv::Point& q : out) far = far && std::hypot(p.x - q.x, p.y - q.y) > separation;
    if (far) out.push_back(p);
    if (static_cast<int>(out.size()) == count) break;
  }
  return out;
}

// How far the surface dips below the lower of two shifts on the straight path between them
// (nearest samples every half pixel): 0 when one is on the other's slope.
double ValleyDepth(const MaskedNccSurface& surface, cv::Point a, cv::Point b) {
  const auto at = [&](double x, double y) {
    const int c = static_cast<int>(std::lround(x)) - surface.shift_x0;
    const int r = static_cast<int>(std::lround(y)) - surface.shift_y0;
    if (r < 0 || c < 0 || r >= surface.ncc.rows || c >= surface.ncc.cols) return -1.0;
    const float v = surface.ncc.at<float>(r, c);
    return std::isfinite(v) ? static_cast<double>(v) : -1.0;
  };
  const double va = at(a.x, a.y), vb = at(b.x, b.y);
  const int steps = std::max(2, static_cast<int>(2.0 * std::hypot(b.x - a.x, b.y - a.y)));
  double lowest = std::min(va, vb);
  for (int k = 1; k < steps; ++k) {
    const double t = static_cast<double>(k) / steps;
    lowest = std::min(lowest, at(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)));
  }
  return std::min(va, vb) - lowest;
}

struct CoarseResult {
  MaskedNccSurface surface;
  NccPeak peak;
  double rotation = 0.0;
  double scale = 1.0;
};

// Vertex offset of a parabola through (-1, a), (0, b), (1, c), in [-0.5, 0.5]; 0 if b is no
// maximum.
double ParabolaVertex(double a, double b, double c) {
  const double d = a - 2.0 * b + c;
  return d < 0.0 ? std::clamp(0.5 * (a - c) / d, -0.5, 0.5) : 0.0;
}

// One search of a template over the orbital pyramid: the coarse surface over the whole window,
// and the coarse-to-fine refinement of a peak.
class PyramidSearch {
 public:
  PyramidSearch(const OrbitalTemplate& templ, const std::vector<MaskedImage>& orbital_pyramid,
                const MaskedNccOptions& coarse_options, const PeakOptions& coarse_peak,
                int refine_radius)
      : templ_(templ),
        orbital_(orbital_pyramid),
        levels_(static_cast<int>(orbital_pyramid.size()) - 1),
        coarse_options_(coarse_options),
        coarse_peak_(coarse_peak),
        refine_radius_(refine_radius) {
    fine_peak_.min_peak = -1.0;
    fine_peak_.min_peak_ratio = 1.0;
  }

  int levels() const { return levels_; }
  const MaskedNccOptions& coarse_options() const { return coarse_options_; }

  // The whole window at the coarsest level for the template warped by (rotation, scale).
  CoarseResult Coarse(double rotation, double scale) const {
    CoarseResult result;
    result.rotation = rotation;
    result.scale = scale;
    const std::vector<MaskedImage> pyramid =
        BuildMaskedPyramid(WarpTemplate(templ_, rotation, scale), levels_);
    result.surface = MaskedNcc(orbital_[levels_].image, orbital_[levels_].mask,
                               pyramid[levels_].image, pyramid[levels_].mask, coarse_options_);
    result.peak = FindPeak(result.surface, coarse_peak_);
    return result;
  }

  // Follows a coarse peak down the pyramid of `warped` to full resolution, in small windows;
  // a peak on a window's edge is followed uphill a few times. The few shifts of a refinement
  // window cost less by direct summation than by FFTs.
  NccPeak Refine(const std::vector<MaskedImage>& warped, cv::Point coarse) const {
    NccPeak fine;
    int x = coarse.x, y = coarse.y;
    for (int level = std::max(levels_ - 1, 0); level >= 0; --level) {
      // Level `levels_` is where the candidate comes from (itself when there is no pyramid).
      int cx = level < levels_ ? 2 * x : x, cy = level < levels_ ? 2 * y : y;
      for (int attempt = 0; attempt < 6; ++attempt) {
        fine = PeakAt(level, warped[level], cx, cy);
        if (!fine.found || !fine.on_border) break;
        cx = fine.shift_x;
        cy = fine.shift_y;
      }
      if (!fine.found) return fine;
      x = fine.shift_x;
      y = fine.shift_y;
    }
    return fine;
  }

  // The peak in the refinement window around shift (x, y) at `level`.
  NccPeak PeakAt(int level, const MaskedImage& t, int x, int y) const {
    MaskedNccOptions at = coarse_options_;
    at.search_window = ShiftWindow::Around(x, y, refine_radius_);
    return FindPeak(
        MaskedNccNaive(orbital_[level].image, orbital_[level].mask, t.image, t.mask, at),
        fine_peak_);
  }

  // How sharp a perfect match of `t` would be: its autocorrelation peak's sharpness.
  double OwnSharpness(const MaskedImage& t) const {
    MaskedNccOptions self = coarse_options_;
    self.search_window = ShiftWindow::Around(0, 0, 1);
    const NccPeak own =
        FindPeak(MaskedNccNaive(t.image, t.mask, t.image, t.mask, self), fine_peak_);
    return own.found ? own.sharpness : 0.0;
  }

 private:
  const OrbitalTemplate& templ_;
  const std::vector<MaskedImage>& orbital_;
  int levels_;
  MaskedNccOptions coarse_options_;
  PeakOptions coarse_peak_;
  PeakOptions fine_peak_;
  int refine_radius_;
};

// The rotation and scale grid of the options (always holding 0 and 1).
std::vector<double> SearchGrid(double centre, double max_change, double step) {
  std::vector<double> grid{centre};
  const int n = static_cast<int>(std::floor(max_change / step + 1e-9));
  for (int k = 1; k <= n; ++k) {
    grid.insert(grid.begin(), centre - k * step);
    grid.push_back(centre + k * step);
  }
  return grid;
}

// Best coarse result over the rotation x scale grid, its rotation and scale refined by a
// parabola between grid values. best.peak.found is false if no shift has enough overlap.
CoarseResult CoarseGridSearch(const PyramidSearch& search, const std::vector<double>& rotations,
                              const std::vector<double>& scales, const ProgressCallback& progress) {
  std::vector<std::vector<double>> values(rotations.size(),
                                          std::vector<double>(scales.size(), -2.0));
  CoarseResult best;
  best.peak.value = -2.0;
  size_t bi = 0, bj = 0;
  for (size_t i = 0; i < rotations.size(); ++i) {
    for (size_t j = 0; j < scales.size(); ++j) {
      CoarseResult r = search.Coarse(rotations[i], scales[j]);
      if (r.peak.found) values[i][j] = r.peak.value;
      if (r.peak.found && r.peak.value > best.peak.value) {
        best = std::move(r);
        bi = i;
        bj = j;
      }
    }
    Report(progress, 0.2 + 0.5 * static_cast<double>(i + 1) / static_cast<double>(rotations.size()),
           "register: coarse search");
  }
  if (!best.peak.found) return best;
  double rotation = best.rotation, scale = best.scale;
  if (bi > 0 && bi + 1 < rotations.size()) {
    rotation += (rotations[1] - rotations[0]) *
                ParabolaVertex(values[bi - 1][bj], values[bi][bj], values[bi + 1][bj]);
  }
  if (bj > 0 && bj + 1 < scales.size()) {
    scale += (scales[1] - scales[0]) *
             ParabolaVertex(values[bi][bj - 1], values[bi][bj], values[bi][bj + 1]);
  }
  if (rotation != best.rotation || scale != best.scale) {
    CoarseResult refined = search.Coarse(rotation, scale);
    if (refined.peak.found && refined.peak.value >= best.peak.value) best = std::move(refined);
  }
  return best;
}

// One warp parameter (the rotation or the scale) refined at full resolution, the other held:
// the peak NCC (shift re-searched around the current peak) sampled `delta` (half a grid step)
// either side of `*value`; while a side is higher the samples walk there, at most
// kMaxRefineWalk steps and within [lowest, highest] (the coarse level's choice can be off by
// more than half a step where the correlation is low); then the vertex of the parabola through
// the three samples, kept if its peak is at least as high. `*peak` and `*warped` follow
// `*value`. Before the walk, the vertex came from samples half a step apart scaled as if they
// were a step apart (twice the parabola's offset), and such overshoots failed the last test:
// most rotations stayed on the half-step grid (docs/notes/benchmarks-history.md, registration).
template <class WarpAt>
void RefineWarpAtFullResolution(const PyramidSearch& search, const WarpAt& warp_at, double delta,
                                double lowest, double highest, double* value, NccPeak* peak,
                                MaskedImage* warped) {
  constexpr int kMaxRefineWalk = 4;
  struct Sample {
    NccPeak peak;
    MaskedImage warped;
    double Value() const { return peak.found ? peak.value : -1.0; }
  };
  const auto sample = [&](double v) {
    Sample s{NccPeak{}, warp_at(v)};
    s.peak = search.PeakAt(0, s.warped, peak->shift_x, peak->shift_y);
    return s;
  };
  Sample below = sample(*value - delta), above = sample(*value + delta);
  for (int k = 0; k < kMaxRefineWalk; ++k) {
    const bool up = above.Value() > peak->value && above.Value() >= below.Value() &&
                    !above.peak.on_border && *value + delta <= highest;
    const bool down =
        !up && below.Value() > peak->value && !below.peak.on_border && *value - delta >= lowest;
    if (!up && !down) break;
    Sample centre{*peak, std::move(*warped)};
    *value += up ? delta : -delta;
    Sample& next = up ? above : below;
    *peak = next.peak;
    *warped = std::move(next.warped);
    if (up) {
      below = std::move(centre);
      above = sample(*value + delta);
    } else {
      above = std::move(centre);
      below = sample(*value - delta);
    }
  }
  const double offset = delta * ParabolaVertex(below.Value(), peak->value, above.Value());
  if (offset == 0.0) return;
  Sample vertex = sample(*value + offset);
  if (vertex.peak.found && !vertex.peak.on_border && vertex.peak.value >= peak->value) {
    *value += offset;
    *peak = vertex.peak;
    *warped = std::move(vertex.warped);
  }
}

// Why a match is not confident, or "" if it is.
std::string Verdict(const OrbitalMatch& m, bool coarse_on_border, bool fine_on_border,
                    const PartConsistency& parts, const OrbitalMatchOptions& options) {
  std::ostringstream why;
  why.precision(3);
  if (coarse_on_border) {
    why << "the best peak lies on the edge of the search window";
  } else if (fine_on_border) {
    why << "the refined peak drifted to the edge of its refinement window";
  } else if (!m.null.valid()) {
    why << "no chance level: " << m.null.samples
        << " correlation samples at wrong shifts (too few on the image, or a flat surface)";
  } else if (!(m.false_match_probability <= options.max_false_match)) {
    why << "false-match probability " << m.false_match_probability << " > max_false_match "
        << options.max_false_match << " (peak " << m.peak_z << " sigma above the chance level, "
        << m.expected_chance_peaks << " chance peaks that high expected)";
  } else if (!parts.consistent()) {
    why << parts.Describe();
  }
  return why.str();
}

}  // namespace

void OrbitalMatchOptions::Check() const {
  template_options.Check();
  RequireOption(search_sigmas > 0.0, "OrbitalMatchOptions.search_sigmas", "> 0");
  RequireOption(max_coarse_radius_px >= 4, "OrbitalMatchOptions.max_coarse_radius_px", ">= 4 px");
  RequireOption(max_levels >= 0 && max_levels <= 8, "OrbitalMatchOptions.max_levels", "0..8");
  RequireOption(min_template_px >= 8, "OrbitalMatchOptions.min_template_px", ">= 8 px");
  RequireOption(refine_radius_px >= 1, "OrbitalMatchOptions.refine_radius_px", ">= 1 px");
  RequireOption(candidates >= 2, "OrbitalMatchOptions.candidates", ">= 2");
  RequireOption(min_valley >= 0.0, "OrbitalMatchOptions.min_valley", ">= 0");
  RequireOption(max_rotation_deg >= 0.0 && max_rotation_deg <= 45.0,
                "OrbitalMatchOptions.max_rotation_deg", "in [0, 45] degrees");
  RequireOption(rotation_step_deg > 0.0, "OrbitalMatchOptions.rotation_step_deg", "> 0 degrees");
  RequireOption(std::isfinite(rotation_floor_deg) && rotation_floor_deg >= 0.0,
                "OrbitalMatchOptions.rotation_floor_deg", ">= 0 degrees");
  RequireOption(rotation_floor_correlation > 0.0 && rotation_floor_correlation < 1.0,
                "OrbitalMatchOptions.rotation_floor_correlation", "in (0, 1)");
  RequireOption(max_scale_change >= 0.0 && max_scale_change < 0.5,
                "OrbitalMatchOptions.max_scale_change", "in [0, 0.5)");
  RequireOption(scale_step > 0.0, "OrbitalMatchOptions.scale_step", "> 0");
  RequireOption(min_overlap_fraction > 0.0 && min_overlap_fraction <= 1.0,
                "OrbitalMatchOptions.min_overlap_fraction", "in (0, 1]");
  RequireOption(max_false_match > 0.0 && max_false_match <= 1.0,
                "OrbitalMatchOptions.max_false_match", "in (0, 1]");
  RequireOption(exclusion_radius_m >= 0.0, "OrbitalMatchOptions.exclusion_radius_m", ">= 0 m");
  RequireOption(min_template_pixels >= 16, "OrbitalMatchOptions.min_template_pixels", ">= 16");
  RequireOption(subpixel_floor_px >= 0.0, "OrbitalMatchOptions.subpixel_floor_px", ">= 0 px");
  RequireOption(null_windows >= 0, "OrbitalMatchOptions.null_windows", ">= 0");
  RequireOption(min_null_samples >= 16, "OrbitalMatchOptions.min_null_samples", ">= 16");
}

Eigen::Vector2d OrbitalMatch::TemplateToOrbital(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d u = p + Eigen::Vector2d(templ.col0, templ.row0);
  return centre_px + shift_px + SimilarityMatrix(rotation_rad, scale) * (u - centre_px);
}

Eigen::Vector2d OrbitalMatch::TurnLeverPx(const Eigen::Vector2d& p) const {
  return kTurn * (p + Eigen::Vector2d(templ.col0, templ.row0) - rotation_pivot_px);
}

Eigen::Vector2d OrbitalMatch::OrbitalToTemplate(const Eigen::Vector2d& v) const {
  const Eigen::Vector2d u =
      centre_px + SimilarityMatrix(rotation_rad, scale).inverse() * (v - centre_px - shift_px);
  return u - Eigen::Vector2d(templ.col0, templ.row0);
}

std::string OrbitalMatch::BriefReport() const {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(3);
  out << orbital << ": ";
  if (!matched) {
    out << "no match (" << reason << ")";
    if (overlaps) out << ", best CC " << correlation << ", ratio " << peak_ratio;
    return out.str();
  }
  out << "shift E " << shift_en_m.x() << " +- " << std::sqrt(shift_covariance_en_m2(0, 0))
      << " m, N " << shift_en_m.y() << " +- " << std::sqrt(shift_covariance_en_m2(1, 1))
      << " m, CC " << correlation << ", ratio " << peak_ratio << ", sharpness " << sharpness
      << " (relative " << relative_sharpness << "), false-match probability "
      << std::setprecision(2) << std::scientific << false_match_probability << " (z " << std::fixed
      << std::setprecision(1) << peak_z << ")" << std::setprecision(3);
  if (rotation_solved) {
    out << ", rotation " << DegFromRad(rotation_rad) << " +- " << DegFromRad(rotation_sigma_rad)
        << " deg";
  }
  if (scale_solved) out << ", scale " << scale;
  return out.str();
}

OrbitalMatch MatchOrthoToOrbital(const OrthoImage& ortho, const OrbitalImage& orbital,
                                 const OrbitalPrior& prior, const OrbitalMatchOptions& options,
                                 const ProgressCallback& progress) {
  options.Check();
  RequireOption(std::isfinite(prior.sigma_m) && prior.sigma_m > 0.0, "OrbitalPrior.sigma_m",
                "> 0 m");
  RequireOption(std::isfinite(prior.expected_rotation_rad) &&
                    std::abs(prior.expected_rotation_rad) < std::numbers::pi / 4.0,
                "OrbitalPrior.expected_rotation_rad", "a finite turn within +-45 degrees");
  RequireOption(IsValid(prior.position), "OrbitalPrior.position",
                "a finite latitude in [-90, 90] degrees and a finite longitude");
  OrbitalMatch out;
  out.orbital = orbital.name();
  Report(progress, 0.0, "register: resample");
  const PixelGrid ortho_grid(ortho.geotransform, ortho.crs_wkt, ortho.source);
  const PixelGrid orbital_grid(orbital.geotransform(), orbital.crs_wkt(), orbital.name());
  const Eigen::Vector3d rover_in_mbf = MbfFromGeographic(prior.body, prior.position);
  const Eigen::Vector2d rover_in_ortho = ortho_grid.PointToPixel(rover_in_mbf);
  const Eigen::Vector2d rover_in_orbital = orbital_grid.PointToPixel(rover_in_mbf);
  if (!rover_in_ortho.allFinite() || !rover_in_orbital.allFinite()) {
    throw Error("the prior position lies outside the domain of the CRS of " +
                (rover_in_ortho.allFinite() ? orbital.name() : ortho.source));
  }
  const Eigen::Matrix2d en_per_px = orbital_grid.EastNorthPerPixel(rover_in_orbital);
  out.gsd_m = 0.5 * (en_per_px.col(0).norm() + en_per_px.col(1).norm());
  out.corrected_position = prior.position;

  out.templ = ResampleToOrbitalGrid(ortho, ortho_grid, orbital_grid, rover_in_ortho,
                                    options.template_options);
  out.template_pixels = out.templ.valid_pixels;
  const OrbitalTemplate& templ = out.templ;
  if (templ.valid_pixels < options.min_template_pixels) {
    // An orbital image that no search could reach is that, not a lack of ortho pixels (an empty
    // template is also what an orthophoto far outside the orbital image's grid resamples to).
    const double reach_px = (options.search_sigmas * prior.sigma_m +
                             std::max(options.template_options.reliable_range_m, 0.0)) /
                                out.gsd_m +
                            2.0;
    const double dx =
        std::max({0.0, -rover_in_orbital.x(), rover_in_orbital.x() - orbital.width()});
    const double dy =
        std::max({0.0, -rover_in_orbital.y(), rover_in_orbital.y() - orbital.height()});
    if (options.template_options.reliable_range_m > 0.0 && std::hypot(dx, dy) > reach_px) {
      out.reason = "the search window does not overlap the orbital image";
      return out;
    }
    out.reason = "the orthophoto has " + std::to_string(templ.valid_pixels) +
                 " valid pixels within the reliable range at the orbital resolution, fewer than " +
                 std::to_string(options.min_template_pixels);
    out.overlaps = true;
    return out;
  }
  out.centre_px =
      Eigen::Vector2d(templ.col0 + templ.image.cols / 2.0, templ.row0 + templ.image.rows / 2.0);

  // The search centre: the guided prior's expected correction of the template centre, a shift
  // of the rover plus the turn of the centre about it.
  const Eigen::Matrix2d expected_turn = SimilarityMatrix(prior.expected_rotation_rad, 1.0);
  out.expected_shift_px =
      en_per_px.inverse() * prior.expected_shift_en_m +
      (expected_turn - Eigen::Matrix2d::Identity()) * (out.centre_px - rover_in_orbital);
  if (!out.expected_shift_px.allFinite()) {
    throw Error("OrbitalPrior.expected_shift_en_m: expected a finite shift in metres");
  }
  const int ex = static_cast<int>(std::lround(out.expected_shift_px.x()));
  const int ey = static_cast<int>(std::lround(out.expected_shift_px.y()));

  // Search radius and pyramid depth.
  const int radius = static_cast<int>(std::ceil(options.search_sigmas * prior.sigma_m / out.gsd_m));
  out.search_radius_px = radius;
  int levels = 0;
  while (levels < options.max_levels && (radius >> levels) > options.max_coarse_radius_px &&
         (std::min(templ.image.rows, templ.image.cols) >> (levels + 1)) >=
             options.min_template_px) {
    ++levels;
  }
  out.levels = levels;
  const int unit = 1 << levels;

  // The orbital pixels the search can reach, read as one window.
  const int margin = 2 * unit;
  PixelWindow window{templ.col0 + ex - radius - margin, templ.row0 + ey - radius - margin,
                     templ.image.cols + 2 * (radius + margin),
                     templ.image.rows + 2 * (radius + margin)};
  const PixelWindow requested = window;
  cv::Mat patch = orbital.ReadWindow(window);
  if (patch.empty()) {
    out.reason = "the search window does not overlap the orbital image";
    return out;
  }
  out.overlaps = true;
  out.window_clipped = window.col0 != requested.col0 || window.row0 != requested.row0 ||
                       window.width != requested.width || window.height != requested.height;
  out.orbital_patch = patch;
  out.orbital_window = window;
  Report(progress, 0.2, "register: pyramid");
  const std::vector<MaskedImage> orbital_pyramid = BuildMaskedPyramid({patch, {}}, levels);

  // Shifts: the template's top-left pixel on window pixel (x, y); the telemetry position is
  // (x0, y0).
  const int x0 = templ.col0 - window.col0, y0 = templ.row0 - window.row0;
  MaskedNccOptions ncc_options;
  ncc_options.min_overlap_fraction = options.min_overlap_fraction;
  ncc_options.search_window =
      ShiftWindow{FloorDiv(x0 + ex - radius, unit), CeilDiv(x0 + ex + radius, unit),
                  FloorDiv(y0 + ey - radius, unit), CeilDiv(y0 + ey + radius, unit)};
  PeakOptions coarse_peak_options;
  coarse_peak_options.exclusion_radius = options.exclusion_radius_m / (out.gsd_m * unit);
  coarse_peak_options.min_peak = -1.0;
  coarse_peak_options.min_peak_ratio = 1.0;

  const PyramidSearch search(templ, orbital_pyramid, ncc_options, coarse_peak_options,
                             options.refine_radius_px);

  // Coarse search over the rotation and scale grid.
  const double step = options.rotation_step_deg * std::numbers::pi / 180.0;
  const std::vector<double> rotations =
      SearchGrid(prior.expected_rotation_rad, RadFromDeg(options.max_rotation_deg), step);
  const std::vector<double> scales = SearchGrid(1.0, options.max_scale_change, options.scale_step);
  const CoarseResult best = CoarseGridSearch(search, rotations, scales, progress);
  if (!best.peak.found) {
    out.reason = "no shift in the search window has enough valid overlap";
    return out;
  }
  out.rotation_rad = best.rotation;
  out.scale = best.scale;
  out.rotation_solved = rotations.size() > 1;
  out.scale_solved = scales.size() > 1;
  out.surface = best.surface.ncc;
  out.surface_shift0 =
      Eigen::Vector2d(best.surface.shift_x0 * unit - x0, best.surface.shift_y0 * unit - y0);

  // Coarse to fine: the best coarse peaks are each followed down the pyramid; the ratio of the
  // best to the best separated runner-up is measured at full resolution, where a true match
  // stands out much more than in the blurred coarse levels.
  Report(progress, 0.75, "register: refine");
  const MaskedImage warped = WarpTemplate(templ, best.rotation, best.scale);
  const std::vector<MaskedImage> template_pyramid = BuildMaskedPyramid(warped, levels);
  const double exclusion_px = std::max(options.exclusion_radius_m / out.gsd_m, 3.0);
  std::vector<cv::Point> candidates =
      TopLocalMaxima(best.surface, options.candidates, std::max(1.0, exclusion_px / unit));
  std::vector<NccPeak> refined(candidates.size());
  tbb::parallel_for(size_t{0}, candidates.size(),
                    [&](size_t k) { refined[k] = search.Refine(template_pyramid, candidates[k]); });
  int best_index = -1;
  for (size_t k = 0; k < refined.size(); ++k) {
    if (refined[k].found && (best_index < 0 || refined[k].value > refined[best_index].value)) {
      best_index = static_cast<int>(k);
    }
  }
  if (best_index < 0) {
    out.reason = "no coarse peak could be refined at full resolution";
    return out;
  }
  NccPeak fine = refined[best_index];
  double second = -1.0;
  for (size_t k = 0; k < refined.size(); ++k) {
    if (!refined[k].found || static_cast<int>(k) == best_index) continue;
    const double d =
        std::hypot(refined[k].shift_x - fine.shift_x, refined[k].shift_y - fine.shift_y);
    // A runner-up on the best peak's own slope (no valley between them) is not a second peak.
    const double valley = ValleyDepth(best.surface, candidates[best_index], candidates[k]);
    if (d > exclusion_px && valley >= options.min_valley) {
      second = std::max(second, refined[k].value);
    }
  }
  out.peak_ratio = second > 0.0 ? fine.value / second : std::numeric_limits<double>::infinity();

  // Rotation and scale refined at full resolution (RefineWarpAtFullResolution).
  MaskedImage final_template = warped;
  for (const bool is_rotation : {true, false}) {
    const std::vector<double>& grid = is_rotation ? rotations : scales;
    if (grid.size() < 2) continue;
    const double delta = 0.5 * (grid[1] - grid[0]);
    double& value = is_rotation ? out.rotation_rad : out.scale;
    const auto warp_at = [&](double v) {
      return is_rotation ? WarpTemplate(templ, v, out.scale)
                         : WarpTemplate(templ, out.rotation_rad, v);
    };
    RefineWarpAtFullResolution(search, warp_at, delta, grid.front() - delta, grid.back() + delta,
                               &value, &fine, &final_template);
  }
  const bool coarse_on_border = [&] {
    const cv::Point c = candidates[best_index];
    const ShiftWindow& w = *ncc_options.search_window;
    return c.x <= w.min_shift_x || c.x >= w.max_shift_x || c.y <= w.min_shift_y ||
           c.y >= w.max_shift_y;
  }();
  out.correlation = fine.value;
  out.sharpness = fine.sharpness;
  const double expected_sharpness =
      search.OwnSharpness(final_template) * std::max(out.correlation, 0.0);
  out.relative_sharpness = expected_sharpness > 0.0 ? out.sharpness / expected_sharpness : 0.0;
  out.shift_px = Eigen::Vector2d(fine.subpixel_x - x0, fine.subpixel_y - y0);
  // The rover moves with the template centre and turns about it.
  const Eigen::Matrix2d warp = SimilarityMatrix(out.rotation_rad, out.scale);
  const Eigen::Vector2d rover_shift_px =
      out.shift_px + (warp - Eigen::Matrix2d::Identity()) * (rover_in_orbital - out.centre_px);
  out.shift_en_m = en_per_px * rover_shift_px;
  const double correlation_area =
      1.0 + 2.0 * std::numbers::pi * std::pow(options.template_options.lowpass_sigma_orbital_px, 2);
  // The template's own shift error, the one its control points share, is the shift's with the
  // rotation held: their turn about the centre is the adjustment's heading to take up (with a
  // low correlation's share of the rotation's error, which MakeControlPoints adds).
  const Eigen::MatrixXd match =
      MatchCovariance(final_template, out.correlation, correlation_area, out.rotation_solved);
  const double base_floor = RadFromDeg(options.rotation_floor_deg);
  const double rotation_floor =
      base_floor * LowCorrelationGrowth(out.correlation, options.rotation_floor_correlation);
  out.rotation_pivot_px = RotationPivot(match, out.centre_px);
  if (out.rotation_solved) {
    out.rotation_sigma_rad = std::sqrt(match(2, 2) + rotation_floor * rotation_floor);
    out.low_correlation_rotation_sigma_rad =
        std::sqrt(rotation_floor * rotation_floor - base_floor * base_floor);
  }
  const Eigen::Matrix2d floor =
      std::pow(options.subpixel_floor_px, 2) * Eigen::Matrix2d::Identity();
  out.shift_covariance_px = ShiftWithRotationHeld(match) + floor;
  out.template_shift_covariance_en_m2 = en_per_px * out.shift_covariance_px * en_per_px.transpose();
  const Eigen::Matrix2d rover_px =
      RoverCovariance(match, kTurn * (rover_in_orbital - out.rotation_pivot_px), rotation_floor) +
      floor;
  out.shift_covariance_en_m2 = en_per_px * rover_px * en_per_px.transpose();
  // The rover moved to its corrected pixel, at the prior's height (the registration does not
  // measure heights).
  if (const auto corrected = orbital_grid.PixelToPoint(rover_in_orbital + rover_shift_px,
                                                       prior.body, prior.position.h)) {
    out.corrected_position = GeographicFromMbf(prior.body, *corrected);
  }

  // The chance level: the peak against the search window's coarse surface at wrong shifts, or,
  // for a small window, against the full-resolution surface in a ring of windows around it.
  const int warps = static_cast<int>(rotations.size() * scales.size());
  const cv::Point coarse_peak(candidates[best_index].x - best.surface.shift_x0,
                              candidates[best_index].y - best.surface.shift_y0);
  // Both images less their local mean (kHighPassSigmaPx): the peak's NCC there, against the null.
  const MaskedImage hp_template = HighPass(final_template, kHighPassSigmaPx);
  const double hp_peak =
      PeakNear(orbital_pyramid[0], hp_template, cv::Point(fine.shift_x, fine.shift_y),
               options.min_overlap_fraction);
  SurfaceNull null;
  if (options.null_windows == 0) {
    const MaskedNccSurface acf =
        Autocorrelation(template_pyramid[levels],
                        std::min(best.surface.ncc.rows, template_pyramid[levels].image.rows),
                        std::min(best.surface.ncc.cols, template_pyramid[levels].image.cols));
    const ShiftWindow full{x0 + ex - radius, x0 + ex + radius, y0 + ey - radius, y0 + ey + radius};
    null = WindowTilesNull(orbital_pyramid[0], hp_template, full,
                           cv::Point(fine.shift_x, fine.shift_y), acf, unit, exclusion_px,
                           options.min_overlap_fraction);
  }
  PeakSignificance significance;
  if (options.null_windows == 0 && null.samples >= options.min_null_samples) {
    out.null_level = 0;
    significance = SignificanceOfPeak(hp_peak, null, 2.0 * radius + 1.0, 2.0 * radius + 1.0, warps);
  } else {
    constexpr int kDefaultNullWindows = 24;
    null = NullWindowTest(orbital, final_template, templ.col0 + ex, templ.row0 + ey, radius,
                          exclusion_px,
                          options.null_windows > 0 ? options.null_windows : kDefaultNullWindows,
                          options.min_overlap_fraction, out);
    out.null_level = 0;
    significance = SignificanceOfPeak(hp_peak, null, 2.0 * radius + 1.0, 2.0 * radius + 1.0, warps);
  }
  out.null = null;
  out.peak_z = significance.z;
  out.expected_chance_peaks = significance.expected_chance_peaks;
  out.false_match_probability = significance.false_match_probability;
  // Structured look-alikes: do the template's quadrants fit where the whole does?
  PartConsistency parts;
  if (options.check_parts && out.false_match_probability <= options.max_false_match) {
    parts = CheckPartConsistency(
        orbital_pyramid[0], hp_template, cv::Point(fine.shift_x, fine.shift_y),
        static_cast<int>(std::ceil(2.0 * exclusion_px)), options.min_overlap_fraction);
    out.parts_tested = parts.tested();
    out.part_contradiction = parts.largest_contradiction();
  }
  out.reason = Verdict(out, coarse_on_border, fine.on_border, parts, options);
  out.matched = out.reason.empty();
  Report(progress, 1.0, "register: done");
  return out;
}

MultiOrbitalMatch MatchOrthoToOrbitals(const OrthoImage& ortho,
                                       const std::vector<OrbitalImage>& orbitals,
                                       const OrbitalPrior& prior,
                                       const OrbitalMatchOptions& options,
                                       const ProgressCallback& progress) {
  MultiOrbitalMatch out;
  const double n = static_cast<double>(std::max<size_t>(orbitals.size(), 1));
  for (size_t k = 0; k < orbitals.size(); ++k) {
    ProgressCallback sub;
    if (progress) {
      sub = [&, k](double fraction, std::string_view stage) {
        return progress((static_cast<double>(k) + fraction) / n, stage);
      };
    }
    out.matches.push_back(MatchOrthoToOrbital(ortho, orbitals[k], prior, options, sub));
    const OrbitalMatch& m = out.matches.back();
    if (m.matched && (out.best < 0 || m.correlation > out.matches[out.best].correlation)) {
      out.best = static_cast<int>(k);
    }
  }
  return out;
}

}  // namespace areomap
