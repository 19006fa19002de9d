// MatchOrthoToOrbital's stages (orbital_match_stages.h) other than the search itself
// (orbital_match_search.cc): the inputs and the template, the search window, the correction and
// its covariance (Forstner), the chance level and the verdict.
#include "orbital_match_stages.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/report_progress.h"
#include "areomap/registration/part_consistency.h"
#include "chance_level.h"
#include "high_pass.h"

namespace areomap::internal {
namespace {

int FloorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int CeilDiv(int a, int b) { return -FloorDiv(-a, b); }

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

// --- Stage 1: checks and template. ---

void CheckMatchInputs(const OrbitalPrior& prior, const OrbitalMatchOptions& options) {
  options.Check();
  RequireOption(std::isfinite(prior.sigma_m) && prior.sigma_m > 0.0, "OrbitalPrior.sigma_m",
                "> 0 m");
  RequireOption(std::isfinite(prior.expected_rotation_rad) &&
                    std::abs(prior.expected_rotation_rad) < std::numbers::pi / 4.0,
                "OrbitalPrior.expected_rotation_rad", "a finite turn within +-45 degrees");
  RequireOption(IsValid(prior.position), "OrbitalPrior.position",
                "a finite latitude in [-90, 90] degrees and a finite longitude");
}

RoverOnGrids LocateRover(const OrthoImage& ortho, const OrbitalImage& orbital,
                         const OrbitalPrior& prior) {
  PixelGrid ortho_grid(ortho.geotransform, ortho.crs_wkt, ortho.source);
  PixelGrid orbital_grid(orbital.geotransform(), orbital.crs_wkt(), orbital.name());
  const Eigen::Vector3d rover_in_mbf = MbfFromGeographic(prior.body, prior.position);
  const Eigen::Vector2d rover_in_ortho = ortho_grid.PointToPixel(rover_in_mbf);
  const Eigen::Vector2d rover_in_orbital = orbital_grid.PointToPixel(rover_in_mbf);
  if (!rover_in_ortho.allFinite() || !rover_in_orbital.allFinite()) {
    throw Error("the prior position lies outside the domain of the CRS of " +
                (rover_in_ortho.allFinite() ? orbital.name() : ortho.source));
  }
  const Eigen::Matrix2d en_per_px = orbital_grid.EastNorthPerPixel(rover_in_orbital);
  const double gsd_m = 0.5 * (en_per_px.col(0).norm() + en_per_px.col(1).norm());
  return RoverOnGrids{std::move(ortho_grid),
                      std::move(orbital_grid),
                      rover_in_ortho,
                      rover_in_orbital,
                      en_per_px,
                      gsd_m};
}

namespace {

// Why a template of too few valid pixels gives no match: an orbital image that no search could
// reach is that, not a lack of ortho pixels (an empty template is also what an orthophoto far
// outside the orbital image's grid resamples to).
void RefuseSmallTemplate(const OrbitalImage& orbital, const OrbitalPrior& prior,
                         const OrbitalMatchOptions& options, const RoverOnGrids& rover,
                         OrbitalMatch& out) {
  const Eigen::Vector2d& rover_in_orbital = rover.in_orbital;
  const double reach_px = (options.search_sigmas * prior.sigma_m +
                           std::max(options.template_options.reliable_range_m, 0.0)) /
                              rover.gsd_m +
                          2.0;
  const double dx = std::max({0.0, -rover_in_orbital.x(), rover_in_orbital.x() - orbital.width()});
  const double dy = std::max({0.0, -rover_in_orbital.y(), rover_in_orbital.y() - orbital.height()});
  if (options.template_options.reliable_range_m > 0.0 && std::hypot(dx, dy) > reach_px) {
    out.reason = "the search window does not overlap the orbital image";
    return;
  }
  out.reason = "the orthophoto has " + std::to_string(out.templ.valid_pixels) +
               " valid pixels within the reliable range at the orbital resolution, fewer than " +
               std::to_string(options.min_template_pixels);
  out.overlaps = true;
}

}  // namespace

bool ResampleTemplate(const OrthoImage& ortho, const OrbitalImage& orbital,
                      const OrbitalPrior& prior, const OrbitalMatchOptions& options,
                      const RoverOnGrids& rover, OrbitalMatch& out) {
  out.templ = ResampleToOrbitalGrid(ortho, rover.ortho_grid, rover.orbital_grid, rover.in_ortho,
                                    options.template_options);
  out.template_pixels = out.templ.valid_pixels;
  const OrbitalTemplate& templ = out.templ;
  if (templ.valid_pixels < options.min_template_pixels) {
    RefuseSmallTemplate(orbital, prior, options, rover, out);
    return false;
  }
  out.centre_px =
      Eigen::Vector2d(templ.col0 + templ.image.cols / 2.0, templ.row0 + templ.image.rows / 2.0);
  return true;
}

// --- Stage 2: search window and pyramid. ---

namespace {

// The search centre (out.expected_shift_px): the guided prior's expected correction of the
// template centre, a shift of the rover plus the turn of the centre about it.
void SetExpectedShift(const OrbitalPrior& prior, const RoverOnGrids& rover, OrbitalMatch& out) {
  const Eigen::Matrix2d expected_turn = SimilarityMatrix(prior.expected_rotation_rad, 1.0);
  out.expected_shift_px =
      rover.en_per_px.inverse() * prior.expected_shift_en_m +
      (expected_turn - Eigen::Matrix2d::Identity()) * (out.centre_px - rover.in_orbital);
  if (!out.expected_shift_px.allFinite()) {
    throw Error("OrbitalPrior.expected_shift_en_m: expected a finite shift in metres");
  }
}

// Pyramid depth: halvings while the search radius exceeds max_coarse_radius_px and the halved
// template keeps min_template_px a side.
int PyramidLevels(int radius, const OrbitalTemplate& templ, const OrbitalMatchOptions& options) {
  int levels = 0;
  while (levels < options.max_levels && (radius >> levels) > options.max_coarse_radius_px &&
         (std::min(templ.image.rows, templ.image.cols) >> (levels + 1)) >=
             options.min_template_px) {
    ++levels;
  }
  return levels;
}

}  // namespace

std::optional<SearchSetup> SetUpSearch(const OrbitalImage& orbital, const OrbitalPrior& prior,
                                       const OrbitalMatchOptions& options,
                                       const RoverOnGrids& rover, OrbitalMatch& out,
                                       const ProgressCallback& progress) {
  const OrbitalTemplate& templ = out.templ;
  SetExpectedShift(prior, rover, out);
  SearchSetup s;
  s.ex = static_cast<int>(std::lround(out.expected_shift_px.x()));
  s.ey = static_cast<int>(std::lround(out.expected_shift_px.y()));
  s.radius = static_cast<int>(std::ceil(options.search_sigmas * prior.sigma_m / out.gsd_m));
  out.search_radius_px = s.radius;
  s.levels = PyramidLevels(s.radius, templ, options);
  out.levels = s.levels;
  s.unit = 1 << s.levels;

  // The orbital pixels the search can reach, read as one window.
  const int margin = 2 * s.unit;
  PixelWindow window{templ.col0 + s.ex - s.radius - margin, templ.row0 + s.ey - s.radius - margin,
                     templ.image.cols + 2 * (s.radius + margin),
                     templ.image.rows + 2 * (s.radius + margin)};
  const PixelWindow requested = window;
  cv::Mat patch = orbital.ReadWindow(window);
  if (patch.empty()) {
    out.reason = "the search window does not overlap the orbital image";
    return std::nullopt;
  }
  out.overlaps = true;
  out.window_clipped = window.col0 != requested.col0 || window.row0 != requested.row0 ||
                       window.width != requested.width || window.height != requested.height;
  out.orbital_patch = patch;
  out.orbital_window = window;
  ReportProgress(progress, 0.2, "register: pyramid");
  s.orbital_pyramid = BuildMaskedPyramid({patch, {}}, s.levels);

  // Shifts: the template's top-left pixel on window pixel (x, y); the telemetry position is
  // (x0, y0).
  s.x0 = templ.col0 - window.col0;
  s.y0 = templ.row0 - window.row0;
  s.coarse_window = ShiftWindow{
      FloorDiv(s.x0 + s.ex - s.radius, s.unit), CeilDiv(s.x0 + s.ex + s.radius, s.unit),
      FloorDiv(s.y0 + s.ey - s.radius, s.unit), CeilDiv(s.y0 + s.ey + s.radius, s.unit)};
  return s;
}

PyramidSearch MakePyramidSearch(const OrbitalTemplate& templ, const SearchSetup& setup,
                                const OrbitalMatchOptions& options, double gsd_m) {
  MaskedNccOptions ncc_options;
  ncc_options.min_overlap_fraction = options.min_overlap_fraction;
  // The coarse surface ranks candidates, each then refined at full resolution by direct sums in
  // double precision: single-precision transforms (masked_ncc.h) are enough for it.
  ncc_options.fft_precision = FftPrecision::kSingle;
  ncc_options.search_window = setup.coarse_window;
  PeakOptions coarse_peak_options;
  coarse_peak_options.exclusion_radius = options.exclusion_radius_m / (gsd_m * setup.unit);
  coarse_peak_options.min_peak = -1.0;
  coarse_peak_options.min_peak_ratio = 1.0;
  return PyramidSearch(templ, setup.orbital_pyramid, ncc_options, coarse_peak_options,
                       options.refine_radius_px);
}

// --- Stage 6: peak measures, the correction and its covariance. ---

void MeasureSharpness(const PyramidSearch& search, const WarpedPeak& final_peak,
                      OrbitalMatch& out) {
  out.sharpness = final_peak.peak.sharpness;
  const double expected_sharpness =
      search.OwnSharpness(final_peak.warped) * std::max(out.correlation, 0.0);
  out.relative_sharpness = expected_sharpness > 0.0 ? out.sharpness / expected_sharpness : 0.0;
}

namespace {

// The covariances of the template's shift and of the rover's, and the rotation's sigma and pivot
// (OrbitalMatch), from Forstner's covariance of `final_template` and the options' floors.
void SetCovariances(const MaskedImage& final_template, const RoverOnGrids& rover,
                    const OrbitalMatchOptions& options, OrbitalMatch& out) {
  const Eigen::Matrix2d& en_per_px = rover.en_per_px;
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
      RoverCovariance(match, kTurn * (rover.in_orbital - out.rotation_pivot_px), rotation_floor) +
      floor;
  out.shift_covariance_en_m2 = en_per_px * rover_px * en_per_px.transpose();
}

}  // namespace

void EstimateCorrection(const WarpedPeak& final_peak, const SearchSetup& setup,
                        const RoverOnGrids& rover, const OrbitalPrior& prior,
                        const OrbitalMatchOptions& options, OrbitalMatch& out) {
  const NccPeak& fine = final_peak.peak;
  out.shift_px = Eigen::Vector2d(fine.subpixel_x - setup.x0, fine.subpixel_y - setup.y0);
  // The rover moves with the template centre and turns about it.
  const Eigen::Matrix2d warp = SimilarityMatrix(out.rotation_rad, out.scale);
  const Eigen::Vector2d rover_shift_px =
      out.shift_px + (warp - Eigen::Matrix2d::Identity()) * (rover.in_orbital - out.centre_px);
  out.shift_en_m = rover.en_per_px * rover_shift_px;
  SetCovariances(final_peak.warped, rover, options, out);
  // The rover moved to its corrected pixel, at the prior's height (the registration does not
  // measure heights).
  if (const auto corrected = rover.orbital_grid.PixelToPoint(rover.in_orbital + rover_shift_px,
                                                             prior.body, prior.position.h)) {
    out.corrected_position = GeographicFromMbf(prior.body, *corrected);
  }
}

// --- Stage 7: the chance level. ---

namespace {

// The null of a large window: the full-resolution surface in the search window's own corner
// tiles, away from the peak's lobe (the template's coarse autocorrelation).
SurfaceNull SearchWindowNull(const SearchSetup& setup, const CoarseStage& coarse,
                             const FineStage& fine, const NccPeak& peak, const HighPassed& hp,
                             const OrbitalMatchOptions& options) {
  const MaskedImage& coarse_template = fine.template_pyramid[setup.levels];
  const cv::Size acf_extent(std::min(coarse.best.surface.ncc.cols, coarse_template.image.cols),
                            std::min(coarse.best.surface.ncc.rows, coarse_template.image.rows));
  const int x0 = setup.x0, y0 = setup.y0, ex = setup.ex, ey = setup.ey, radius = setup.radius;
  const ShiftWindow full{x0 + ex - radius, x0 + ex + radius, y0 + ey - radius, y0 + ey + radius};
  return WindowTilesNull(hp.window, hp.templ, full, cv::Point(peak.shift_x, peak.shift_y),
                         coarse_template, acf_extent, setup.unit, fine.exclusion_px,
                         options.min_overlap_fraction);
}

}  // namespace

HighPassedImage HighPassedWindow(const SearchSetup& setup, const OrbitalTemplate& templ) {
  const MaskedImage& window = setup.orbital_pyramid[0];
  return HighPassedImage(window, NullReachesAllOf(window.image.size(), templ.image.size()));
}

// The peak against the search window's surface at wrong shifts, or, for a small window, against
// the full-resolution surface in a ring of windows around it.
void MeasureChanceLevel(const OrbitalImage& orbital, const OrbitalTemplate& templ,
                        const SearchSetup& setup, const CoarseStage& coarse, const FineStage& fine,
                        const WarpedPeak& final_peak, const HighPassed& hp,
                        const OrbitalMatchOptions& options, OrbitalMatch& out) {
  const int radius = setup.radius;
  const int warps = static_cast<int>(coarse.rotations.size() * coarse.scales.size());
  const NccPeak& peak = final_peak.peak;
  // Both images less their local mean (kHighPassSigmaPx): the peak's NCC there, against the null.
  const double hp_peak = PeakNear(hp.window, hp.templ, cv::Point(peak.shift_x, peak.shift_y),
                                  options.min_overlap_fraction);
  SurfaceNull null;
  if (options.null_windows == 0) {
    null = SearchWindowNull(setup, coarse, fine, peak, hp, options);
  }
  PeakSignificance significance;
  if (options.null_windows == 0 && null.samples >= options.min_null_samples) {
    out.null_level = 0;
    significance = SignificanceOfPeak(hp_peak, null, 2.0 * radius + 1.0, 2.0 * radius + 1.0, warps);
  } else {
    constexpr int kDefaultNullWindows = 24;
    null = NullWindowTest(orbital, final_peak.warped, templ.col0 + setup.ex, templ.row0 + setup.ey,
                          radius, fine.exclusion_px,
                          options.null_windows > 0 ? options.null_windows : kDefaultNullWindows,
                          options.min_overlap_fraction, out);
    out.null_level = 0;
    significance = SignificanceOfPeak(hp_peak, null, 2.0 * radius + 1.0, 2.0 * radius + 1.0, warps);
  }
  out.null = null;
  out.peak_z = significance.z;
  out.expected_chance_peaks = significance.expected_chance_peaks;
  out.false_match_probability = significance.false_match_probability;
}

PartConsistency TestParts(const FineStage& fine, const WarpedPeak& final_peak, const HighPassed& hp,
                          const OrbitalMatchOptions& options) {
  if (!options.check_parts) return {};
  // Structured look-alikes: do the template's quadrants fit where the whole does?
  const int radius = static_cast<int>(std::ceil(2.0 * fine.exclusion_px));
  const cv::Point match(final_peak.peak.shift_x, final_peak.peak.shift_y);
  ShiftWindow local;
  const MaskedImage crop =
      hp.window.Reach(ShiftWindow::Around(match.x, match.y, radius), hp.templ.image.size(), &local);
  if (crop.image.empty()) return {};
  return CheckPartConsistency(crop, hp.templ,
                              cv::Point(local.min_shift_x + radius, local.min_shift_y + radius),
                              radius, options.min_overlap_fraction);
}

// --- Stage 8: the verdict. ---

void Decide(const SearchSetup& setup, const FineStage& fine, const WarpedPeak& final_peak,
            const PartConsistency& parts, const OrbitalMatchOptions& options, OrbitalMatch& out) {
  const bool coarse_on_border = [&] {
    const cv::Point c = fine.coarse_peak;
    const ShiftWindow& w = setup.coarse_window;
    return c.x <= w.min_shift_x || c.x >= w.max_shift_x || c.y <= w.min_shift_y ||
           c.y >= w.max_shift_y;
  }();
  // The parts speak only for a peak above chance.
  const PartConsistency counted =
      out.false_match_probability <= options.max_false_match ? parts : PartConsistency{};
  out.parts_tested = counted.tested();
  out.part_contradiction = counted.largest_contradiction();
  out.reason = Verdict(out, coarse_on_border, final_peak.peak.on_border, counted, options);
  out.matched = out.reason.empty();
}

}  // namespace areomap::internal
