// Orbital-ground registration: where does the rover orthophoto lie on an orbital image?
//
// Contract: MatchOrthoToOrbital resamples the orthophoto to the orbital grid
// (orbital_template.h) and matches it by masked NCC (masked_ncc.h) coarse-to-fine over a pyramid
// within the prior's search window (search_sigmas x its 1-sigma radius), optionally over a grid
// of small rotations and scale changes. It returns the correction with its covariance (Forstner's
// correlation precision plus floors) and its confidence: peak CC, peak ratio, relative sharpness
// and the probability that the peak is a chance alignment (peak_significance.h), which is the one
// accept rule (OrbitalMatchOptions::max_false_match), with a parts test (part_consistency.h).
// Rationale: like JPL's Mars Global Localization and VICAR marsautoloco, a position comes with
// its confidence. Cost ~0.05-0.3 s per site; method and measurements in docs/benchmarks.md
// ("Masked NCC and orbital registration"), history in docs/notes/benchmarks-history.md.
//
// Frames and units: shifts are in orbital pixels (columns, rows; GDAL pixel convention) and in
// metres east/north in the local level frame at the rover; rotations in radians, counter-
// clockwise on the map (east towards north). The correction maps where the telemetry
// georeference puts a ground point on the orbital image to where the image shows it.
//
// Failure: a refused or impossible match is a result (matched = false with a reason), never a
// position; bad options, a CRS not on Mars or a cancelled progress callback throw areomap::Error.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/map/geodesy.h"
#include "areomap/map/progress.h"
#include "areomap/registration/orbital_image.h"
#include "areomap/registration/orbital_template.h"
#include "areomap/registration/peak_significance.h"

namespace areomap {

// Where telemetry puts the rover, and how far off that may be.
struct OrbitalPrior {
  // The rover: planetocentric latitude and east longitude [rad] of its foot point on `body`'s
  // ellipsoid and its height above it [m] (geodesy.h MbfFromGeographic), e.g.
  // SiteGeoreference::Origin(). Its pixels are those of that point itself (PointToPixel).
  Geographic position;
  Body body = Body::Mars2000();
  double sigma_m = 10.0;  // Horizontal 1-sigma position uncertainty [m], > 0.
  // A guided prior (e.g. from a bundle adjustment) expects the telemetry georeference to be off:
  // the rover lies this far east/north of `position` [m] and the orthophoto is turned by this
  // much (counter-clockwise on the map [rad]). The search window (search_sigmas x sigma_m) and
  // the rotation grid (+-max_rotation_deg) are centred on that correction; the reported
  // correction stays relative to `position` and the orthophoto's own georeference.
  Eigen::Vector2d expected_shift_en_m = Eigen::Vector2d::Zero();
  double expected_rotation_rad = 0.0;
};

struct OrbitalMatchOptions {
  TemplateOptions template_options;
  double search_sigmas = 3.0;     // Search window half side = this x prior sigma, > 0.
  int max_coarse_radius_px = 24;  // Pyramid depth: coarsest search radius <= this [px], >= 4.
  int max_levels = 4;             // At most this many halvings, >= 0.
  int min_template_px = 32;       // Coarsest template's shorter side >= this [px], >= 8.
  int refine_radius_px = 1;       // Search radius at each finer level [px], >= 1.
  int candidates = 6;             // Coarse peaks followed to full resolution, >= 2.
  // A runner-up counts as a second peak only if the coarse surface dips at least this much
  // [NCC] between it and the best (otherwise it sits on the best peak's slope), >= 0.
  double min_valley = 0.02;
  double max_rotation_deg = 0.0;      // Rotations searched: +-this [deg], >= 0 (0 = none).
  double rotation_step_deg = 1.0;     // Rotation grid step [deg], > 0.
  double max_scale_change = 0.0;      // Scales searched: 1 +- this, in [0, 0.5) (0 = none).
  double scale_step = 0.02;           // Scale grid step, > 0.
  double min_overlap_fraction = 0.7;  // Of the template's valid pixels, for a shift to count.
  // The accept rule: a match is confident only if the probability that its peak is a chance
  // alignment (peak_significance.h: the peak against the correlation surface at wrong shifts,
  // with the number of independent trials of the window and of the warps searched) is at most
  // this, in (0, 1]. It is the rate of false acceptances where the template's place is not in
  // the window (docs/benchmarks.md, "Registration decision", has the measured curve).
  double max_false_match = 1e-3;
  // A match far above chance is also refused where a quadrant of the template fits clearly
  // better elsewhere (part_consistency.h: a look-alike of part of the template, such as one
  // crater wall on another crater); tested only where the false-match probability passes.
  // Off only for experiments.
  bool check_parts = true;
  double exclusion_radius_m = 3.0;  // Runner-ups lie farther than this [m] and 3 px from the best.
  int min_template_pixels = 400;    // Fewer valid template pixels at full resolution: no match.
  // Accuracy floor of area correlation between images of different sensors and illumination
  // (shading moves edges; resampling), added in quadrature to the noise-driven sigma [px], >= 0.
  // Calibrated on generated sites (OrbitalMatchStatistics; docs/notes/benchmarks-history.md).
  double subpixel_floor_px = 0.09;
  // The same for a solved rotation, added in quadrature to its noise-driven sigma [deg], >= 0:
  // it moves the rover by this times its lever from where the template's texture pins the
  // shift. Calibrated on generated sites with heading errors (OrbitalMatchStatistics.
  // HonestUnderHeadingErrors; docs/notes/benchmarks-history.md, "The rotation refined").
  double rotation_floor_deg = 0.1;
  // Below this peak correlation, in (0, 1), the rotation's floor grows as the square of the
  // residual-to-signal variance ratio g(rho) = (1 - rho^2) / rho^2: rotation_floor_deg x
  // (g(rho) / g(rotation_floor_correlation))^2 (0.28 deg at CC 0.5, 0.87 deg at 0.4); at or
  // above it the floor is rotation_floor_deg. Chosen on generated traverses
  // (areomap_bench_registration_truth; docs/notes/benchmarks-history.md, "The rotation's
  // sigma at low correlation").
  double rotation_floor_correlation = 0.6;
  // Where the chance level's null statistics come from: the full-resolution NCC of the template
  // at the match's rotation and scale, both images less their local mean (3 px), at wrong
  // shifts. With 0, the search window's four corner tiles of 48 x 48 shifts (the whole window
  // under 96 px a side), where the template lies on the image, minus the peak's lobe (its
  // autocorrelation >= 0.2, or within exclusion_radius_m); where that leaves fewer than
  // min_null_samples, or with null_windows > 0 (a small guided window), at least null_windows (24
  // when 0) windows of the search window's size tiling a ring around it (every shift farther than
  // exclusion_radius_m from every shift of the window), at least half of them on the image.
  int null_windows = 0;        // >= 0.
  int min_null_samples = 100;  // >= 16.
  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

struct OrbitalMatch {
  std::string orbital;          // The orbital image's name.
  bool overlaps = false;        // The search window reaches the orbital image.
  bool matched = false;         // A confident match (false_match_probability <= the maximum).
  std::string reason;           // Why there is no match; empty when matched.
  bool window_clipped = false;  // The search window ran over the image's edge.

  // The correction (orbital pixels): orbital pixel u, where the telemetry georeference puts a
  // ground point, shows that point at centre + shift + A (u - centre) with A = scale R(rotation).
  Eigen::Vector2d shift_px = Eigen::Vector2d::Zero();
  // The shift's covariance [px^2] (Forstner's, plus OrbitalMatchOptions::subpixel_floor_px):
  // the template's shared error, with the rotation held.
  Eigen::Matrix2d shift_covariance_px = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d template_shift_covariance_en_m2 = Eigen::Matrix2d::Zero();  // Same, in [m^2].
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();  // Template centre on the orbital image.
  double rotation_rad = 0.0;
  double scale = 1.0;
  bool rotation_solved = false;
  bool scale_solved = false;
  // 1 sigma of the rotation [rad]: Forstner's (with the shift) and the floor
  // (OrbitalMatchOptions::rotation_floor_deg, grown below rotation_floor_correlation) in
  // quadrature; NaN unless rotation_solved.
  double rotation_sigma_rad = std::numeric_limits<double>::quiet_NaN();
  // The part of that sigma a low correlation adds: the floor's growth below
  // OrbitalMatchOptions::rotation_floor_correlation, sqrt(floor(rho)^2 - rotation_floor^2)
  // [rad]; 0 at or above it and unless rotation_solved. The control points carry it
  // (MakeControlPoints); the rest of the rotation's error their spread conveys.
  double low_correlation_rotation_sigma_rad = 0.0;
  // The orbital pixel about which a rotation error turns the template: where its texture pins
  // the shift (the template centre moved by kTurn b, b = cov(shift, rotation) / var(rotation)).
  // On the orbital image, where the telemetry georeference puts it (as centre_px). A rotation
  // error delta [rad] moves template pixel p by delta x TurnLeverPx(p). The template centre
  // unless rotation_solved.
  Eigen::Vector2d rotation_pivot_px = Eigen::Vector2d::Zero();
  // The correction of the rover itself, east and north [m]: shift_px + (A - I) (rover -
  // centre) in metres. Its covariance [m^2]: with a solved rotation, the shift's and the
  // rotation's jointly (their Forstner covariance and the rotation's floor, the rotation's
  // error times the rover's lever from where the template's texture pins the shift) plus the
  // shift's floor; else template_shift_covariance_en_m2.
  Eigen::Vector2d shift_en_m = Eigen::Vector2d::Zero();
  Eigen::Matrix2d shift_covariance_en_m2 = Eigen::Matrix2d::Zero();
  // The rover's position moved by shift_en_m, in OrbitalPrior::position's convention (same
  // body, same height).
  Geographic corrected_position;

  double correlation = 0.0;  // NCC at the full-resolution peak.
  double peak_ratio = 0.0;   // Best / best separated runner-up, both refined to full resolution.
  double sharpness = 0.0;    // Mean NCC drop to the 8 neighbours at full resolution.
  double relative_sharpness = 0.0;  // sharpness / (CC x the template autocorrelation's drop).
  double gsd_m = 0.0;               // Orbital pixel size at the rover [m].
  int levels = 0;                   // Pyramid halvings used.
  int search_radius_px = 0;         // Full-resolution search radius [px].
  int template_pixels = 0;          // Valid template pixels at full resolution.
  // The chance level (peak_significance.h): the probability that the peak is a chance
  // alignment, and what it follows from: z = (peak - mean) / stddev of the null surface, the
  // expected number of chance peaks at least that high in the window, the null's samples and
  // mean, stddev and smoothness (lambda_x, lambda_y [1/px^2] at the surface's level).
  double false_match_probability = 1.0;
  // The template's quadrants correlated alone around the match (part_consistency.h): how many
  // were tested, and the largest contradiction among those that fit clearly elsewhere [their
  // chance spreads; 0 when none does]; at kMinContradiction or more the match is refused.
  int parts_tested = 0;
  double part_contradiction = 0.0;
  double expected_chance_peaks = std::numeric_limits<double>::infinity();
  double peak_z = std::numeric_limits<double>::quiet_NaN();
  SurfaceNull null;
  int null_level = 0;  // Pyramid level of the surface the null and z are measured on (0).
  // With a ring of windows (OrbitalMatchOptions::null_windows): windows tested, how many reach
  // the full-resolution peak CC, and the highest CC among them (0, 0 and NaN without a ring).
  int null_windows = 0;
  int null_reaching = 0;
  double null_highest = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector2d expected_shift_px = Eigen::Vector2d::Zero();  // Search centre (guided prior).

  // The correlation surface of the whole search window at the coarsest level (CV_32F, NaN where
  // undefined), one pixel per 2^levels orbital pixels; surface_shift0 is the correction
  // (full-resolution px) of its pixel (0, 0), before rotation.
  cv::Mat surface;
  Eigen::Vector2d surface_shift0 = Eigen::Vector2d::Zero();

  // What verification and control points need: the template on the orbital grid (telemetry
  // georeference), and the orbital pixels around the match.
  OrbitalTemplate templ;
  cv::Mat orbital_patch;  // CV_32F, NaN where invalid.
  PixelWindow orbital_window;

  // Orbital pixel at which template pixel coordinate `p` (GDAL convention) lies under the
  // correction, and the inverse.
  Eigen::Vector2d TemplateToOrbital(const Eigen::Vector2d& p) const;
  Eigen::Vector2d OrbitalToTemplate(const Eigen::Vector2d& u) const;
  // How far a rotation error of 1 rad moves template pixel coordinate `p` (as in
  // TemplateToOrbital) on the orbital image [px per rad]: its offset from rotation_pivot_px
  // turned a quarter counter-clockwise on the map.
  Eigen::Vector2d TurnLeverPx(const Eigen::Vector2d& p) const;
  // One line: image, verdict, shift [m] with sigma, CC, ratio.
  std::string BriefReport() const;
};

// Matches `ortho` onto `orbital` around `prior`. A failure to match (no overlap, too few
// valid pixels, low confidence) is a result with matched = false and a reason. Throws
// areomap::Error if the options fail Check(), a CRS is not on Mars (the message names the
// file), or the progress callback asks to stop.
OrbitalMatch MatchOrthoToOrbital(const OrthoImage& ortho, const OrbitalImage& orbital,
                                 const OrbitalPrior& prior, const OrbitalMatchOptions& options = {},
                                 const ProgressCallback& progress = nullptr);

// Several orbital images (the dissertation's seven-image test): every image is matched; the
// best is the confident match with the highest correlation.
struct MultiOrbitalMatch {
  std::vector<OrbitalMatch> matches;  // One per image, in input order.
  int best = -1;                      // Index of the best confident match; -1 if none.
};
MultiOrbitalMatch MatchOrthoToOrbitals(const OrthoImage& ortho,
                                       const std::vector<OrbitalImage>& orbitals,
                                       const OrbitalPrior& prior,
                                       const OrbitalMatchOptions& options = {},
                                       const ProgressCallback& progress = nullptr);

}  // namespace areomap
