// The search machinery of MatchOrthoToOrbital's stages (orbital_match_stages.h): the warped
// template, the pyramid search, the coarse rotation/scale grid, the coarse-to-fine refinement of
// its peaks and the full-resolution refinement of the rotation and scale (stages 3 to 5).
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/geodesy.h"
#include "areomap/map/report_progress.h"
#include "orbital_match_stages.h"

namespace areomap::internal {
namespace {

// The template warped by A about its centre: W(q) = T(A^-1 (q - c) + c).
MaskedImage WarpTemplate(const OrbitalTemplate& templ, double rotation, double scale) {
  MaskedImage out;
  if (IsIdentityWarp(rotation, scale)) {
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

// Vertex offset of a parabola through (-1, a), (0, b), (1, c), in [-0.5, 0.5]; 0 if b is no
// maximum.
double ParabolaVertex(double a, double b, double c) {
  const double d = a - 2.0 * b + c;
  return d < 0.0 ? std::clamp(0.5 * (a - c) / d, -0.5, 0.5) : 0.0;
}

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
    ReportProgress(progress,
                   0.2 + 0.5 * static_cast<double>(i + 1) / static_cast<double>(rotations.size()),
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
// `*value`. The vertex's offset is scaled by `delta`, the samples' spacing: scaled by a whole
// step it overshoots and fails the last test (docs/notes/benchmarks-history.md, "The rotation
// refined").
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
    s.peak = search.PeakAt(0, PreparedTemplate(s.warped.image, s.warped.mask), peak->shift_x,
                           peak->shift_y);
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

// The index of the highest found peak; -1 when none was found.
int HighestPeak(const std::vector<NccPeak>& refined) {
  int best_index = -1;
  for (size_t k = 0; k < refined.size(); ++k) {
    if (refined[k].found && (best_index < 0 || refined[k].value > refined[best_index].value)) {
      best_index = static_cast<int>(k);
    }
  }
  return best_index;
}

// The highest refined peak other than the best that is a peak of its own: farther than
// `exclusion_px` from it, with a valley of at least `min_valley` between their coarse shifts on
// `coarse_surface`; -1 when there is none.
double SeparatedRunnerUp(const std::vector<NccPeak>& refined,
                         const std::vector<cv::Point>& candidates, int best_index,
                         const MaskedNccSurface& coarse_surface, double exclusion_px,
                         double min_valley) {
  const NccPeak& fine = refined[best_index];
  double second = -1.0;
  for (size_t k = 0; k < refined.size(); ++k) {
    if (!refined[k].found || static_cast<int>(k) == best_index) continue;
    const double d =
        std::hypot(refined[k].shift_x - fine.shift_x, refined[k].shift_y - fine.shift_y);
    // A runner-up on the best peak's own slope (no valley between them) is not a second peak.
    const double valley = ValleyDepth(coarse_surface, candidates[best_index], candidates[k]);
    if (d > exclusion_px && valley >= min_valley) {
      second = std::max(second, refined[k].value);
    }
  }
  return second;
}

}  // namespace

Eigen::Matrix2d SimilarityMatrix(double rotation, double scale) {
  // Counter-clockwise on a north-up map = clockwise in (column, row) pixel axes.
  const double c = std::cos(rotation), s = std::sin(rotation);
  Eigen::Matrix2d a;
  a << c, s, -s, c;
  return scale * a;
}

PyramidSearch::PyramidSearch(const OrbitalTemplate& templ,
                             const std::vector<MaskedImage>& orbital_pyramid,
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

CoarseResult PyramidSearch::Coarse(double rotation, double scale) const {
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

// The few shifts of a refinement window cost less by direct summation than by FFTs.
NccPeak PyramidSearch::Refine(const std::vector<PreparedTemplate>& warped, cv::Point coarse) const {
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

NccPeak PyramidSearch::PeakAt(int level, const PreparedTemplate& t, int x, int y) const {
  MaskedNccOptions at = coarse_options_;
  at.search_window = ShiftWindow::Around(x, y, refine_radius_);
  at.method = NccMethod::kDirect;
  return FindPeak(MaskedNcc(orbital_[level].image, orbital_[level].mask, t, at), fine_peak_);
}

double PyramidSearch::OwnSharpness(const MaskedImage& t) const {
  MaskedNccOptions self = coarse_options_;
  self.search_window = ShiftWindow::Around(0, 0, 1);
  const NccPeak own = FindPeak(MaskedNccNaive(t.image, t.mask, t.image, t.mask, self), fine_peak_);
  return own.found ? own.sharpness : 0.0;
}

// --- Stage 3: coarse search over the rotation and scale grid. ---

std::optional<CoarseStage> SearchCoarse(const PyramidSearch& search, const SearchSetup& setup,
                                        const OrbitalPrior& prior,
                                        const OrbitalMatchOptions& options, OrbitalMatch& out,
                                        const ProgressCallback& progress) {
  CoarseStage c;
  const double step = options.rotation_step_deg * std::numbers::pi / 180.0;
  c.rotations = SearchGrid(prior.expected_rotation_rad, RadFromDeg(options.max_rotation_deg), step);
  c.scales = SearchGrid(1.0, options.max_scale_change, options.scale_step);
  c.best = CoarseGridSearch(search, c.rotations, c.scales, progress);
  if (!c.best.peak.found) {
    out.reason = "no shift in the search window has enough valid overlap";
    return std::nullopt;
  }
  out.rotation_rad = c.best.rotation;
  out.scale = c.best.scale;
  out.rotation_solved = c.rotations.size() > 1;
  out.scale_solved = c.scales.size() > 1;
  out.surface = c.best.surface.ncc;
  out.surface_shift0 = Eigen::Vector2d(c.best.surface.shift_x0 * setup.unit - setup.x0,
                                       c.best.surface.shift_y0 * setup.unit - setup.y0);
  return c;
}

// --- Stage 4: coarse to fine, and the peak ratio. ---

// The best coarse peaks are each followed down the pyramid; the ratio of the best to the best
// separated runner-up is measured at full resolution, where a true match stands out much more
// than in the blurred coarse levels.
std::optional<FineStage> RefineCoarsePeaks(const PyramidSearch& search,
                                           const OrbitalTemplate& templ, const SearchSetup& setup,
                                           const CoarseStage& coarse,
                                           const OrbitalMatchOptions& options, OrbitalMatch& out,
                                           const ProgressCallback& progress) {
  ReportProgress(progress, 0.75, "register: refine");
  FineStage f;
  f.warped = WarpTemplate(templ, coarse.best.rotation, coarse.best.scale);
  f.template_pyramid = BuildMaskedPyramid(f.warped, setup.levels);
  // Every candidate is followed down the same template pyramid: prepared once.
  std::vector<PreparedTemplate> prepared;
  for (const MaskedImage& level : f.template_pyramid)
    prepared.emplace_back(level.image, level.mask);
  f.exclusion_px = std::max(options.exclusion_radius_m / out.gsd_m, 3.0);
  const std::vector<cv::Point> candidates = TopLocalMaxima(
      coarse.best.surface, options.candidates, std::max(1.0, f.exclusion_px / setup.unit));
  std::vector<NccPeak> refined(candidates.size());
  tbb::parallel_for(size_t{0}, candidates.size(),
                    [&](size_t k) { refined[k] = search.Refine(prepared, candidates[k]); });
  const int best_index = HighestPeak(refined);
  if (best_index < 0) {
    out.reason = "no coarse peak could be refined at full resolution";
    return std::nullopt;
  }
  f.coarse_peak = candidates[best_index];
  f.peak = refined[best_index];
  const double second = SeparatedRunnerUp(refined, candidates, best_index, coarse.best.surface,
                                          f.exclusion_px, options.min_valley);
  out.peak_ratio = second > 0.0 ? f.peak.value / second : std::numeric_limits<double>::infinity();
  return f;
}

// --- Stage 5: rotation and scale refined at full resolution (RefineWarpAtFullResolution). ---

WarpedPeak RefineWarp(const PyramidSearch& search, const OrbitalTemplate& templ,
                      const CoarseStage& coarse, const FineStage& fine, OrbitalMatch& out) {
  WarpedPeak result{fine.peak, fine.warped};
  for (const bool is_rotation : {true, false}) {
    const std::vector<double>& grid = is_rotation ? coarse.rotations : coarse.scales;
    if (grid.size() < 2) continue;
    const double delta = 0.5 * (grid[1] - grid[0]);
    double& value = is_rotation ? out.rotation_rad : out.scale;
    const auto warp_at = [&](double v) {
      return is_rotation ? WarpTemplate(templ, v, out.scale)
                         : WarpTemplate(templ, out.rotation_rad, v);
    };
    RefineWarpAtFullResolution(search, warp_at, delta, grid.front() - delta, grid.back() + delta,
                               &value, &result.peak, &result.warped);
  }
  return result;
}

}  // namespace areomap::internal
