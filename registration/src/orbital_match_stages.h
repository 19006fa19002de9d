// The stages of MatchOrthoToOrbital (orbital_match.h), in the order it runs them, and the small
// structs each hands to the next. Internal header.
//
// Pixels are orbital pixels (GDAL convention) unless named otherwise; a shift (x, y) places the
// template's top-left pixel on pixel (x, y) of the orbital window read for the search
// (masked_ncc.h). A stage that finds no match writes the reason into the OrbitalMatch and returns
// std::nullopt (or false); bad input throws areomap::Error, as MatchOrthoToOrbital documents.
#pragma once

#include <optional>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/map/progress.h"
#include "areomap/registration/masked_ncc.h"
#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_match.h"
#include "areomap/registration/orbital_pyramid.h"
#include "areomap/registration/part_consistency.h"
#include "high_pass.h"

namespace areomap::internal {

// scale R(rotation): counter-clockwise on a north-up map = clockwise in (column, row) pixel axes.
Eigen::Matrix2d SimilarityMatrix(double rotation, double scale);

// Whether (rotation, scale) leaves the template as resampled: WarpTemplate then returns it as it
// is.
inline bool IsIdentityWarp(double rotation, double scale) {
  return rotation == 0.0 && scale == 1.0;
}

// d SimilarityMatrix(rotation, 1) / d rotation at 0: how a turn moves a point about the centre.
inline const Eigen::Matrix2d kTurn = (Eigen::Matrix2d() << 0.0, 1.0, -1.0, 0.0).finished();

// The coarsest level's surface for one warp of the template, and its peak.
struct CoarseResult {
  MaskedNccSurface surface;
  NccPeak peak;
  double rotation = 0.0;  // [rad]
  double scale = 1.0;
};

// One search of a template over the orbital pyramid: the coarse surface over the whole window,
// and the coarse-to-fine refinement of a peak. Holds references to the template and the pyramid.
class PyramidSearch {
 public:
  PyramidSearch(const OrbitalTemplate& templ, const std::vector<MaskedImage>& orbital_pyramid,
                const MaskedNccOptions& coarse_options, const PeakOptions& coarse_peak,
                int refine_radius);

  int levels() const { return levels_; }
  const MaskedNccOptions& coarse_options() const { return coarse_options_; }

  // The whole window at the coarsest level for the template warped by (rotation, scale).
  CoarseResult Coarse(double rotation, double scale) const;
  // Follows a coarse peak down the pyramid of `warped` (its levels prepared) to full resolution,
  // in small windows; a peak on a window's edge is followed uphill a few times.
  NccPeak Refine(const std::vector<PreparedTemplate>& warped, cv::Point coarse) const;
  // The peak in the refinement window around shift (x, y) at `level`.
  NccPeak PeakAt(int level, const PreparedTemplate& t, int x, int y) const;
  // How sharp a perfect match of `t` would be: its autocorrelation peak's sharpness.
  double OwnSharpness(const MaskedImage& t) const;

 private:
  const OrbitalTemplate& templ_;
  const std::vector<MaskedImage>& orbital_;
  int levels_;
  MaskedNccOptions coarse_options_;
  PeakOptions coarse_peak_;
  PeakOptions fine_peak_;
  int refine_radius_;
};

// --- Stage 1: checks and template. ---

// Throws areomap::Error naming the field if the options or the prior are invalid.
void CheckMatchInputs(const OrbitalPrior& prior, const OrbitalMatchOptions& options);

// The rover on both pixel grids.
struct RoverOnGrids {
  PixelGrid ortho_grid;
  PixelGrid orbital_grid;
  Eigen::Vector2d in_ortho;    // [ortho px]
  Eigen::Vector2d in_orbital;  // [orbital px]
  Eigen::Matrix2d en_per_px;   // East/north [m] per orbital pixel step at the rover.
  double gsd_m = 0.0;          // Orbital pixel size at the rover [m].
};

// Throws areomap::Error if a CRS is not on Mars or the prior lies outside a CRS's domain.
RoverOnGrids LocateRover(const OrthoImage& ortho, const OrbitalImage& orbital,
                         const OrbitalPrior& prior);

// Sets out.templ, template_pixels and centre_px; false (with out.reason) when the template has
// too few valid pixels or the orbital image lies out of the search's reach.
bool ResampleTemplate(const OrthoImage& ortho, const OrbitalImage& orbital,
                      const OrbitalPrior& prior, const OrbitalMatchOptions& options,
                      const RoverOnGrids& rover, OrbitalMatch& out);

// --- Stage 2: search window and pyramid. ---

struct SearchSetup {
  int ex = 0;  // Search centre: the expected shift, rounded [px].
  int ey = 0;
  int radius = 0;  // Search radius at full resolution [px].
  int levels = 0;  // Pyramid halvings.
  int unit = 1;    // 2^levels: full-resolution pixels per coarsest pixel.
  int x0 = 0;      // The telemetry position's shift on the window [px].
  int y0 = 0;
  ShiftWindow coarse_window;  // The shifts searched at the coarsest level [coarsest px].
  std::vector<MaskedImage> orbital_pyramid;  // Of the window read (level 0 = full resolution).
};

// Sets out.expected_shift_px, search_radius_px, levels and, when the window reaches the image,
// overlaps, window_clipped, orbital_patch and orbital_window. Throws areomap::Error for a
// non-finite expected shift.
std::optional<SearchSetup> SetUpSearch(const OrbitalImage& orbital, const OrbitalPrior& prior,
                                       const OrbitalMatchOptions& options,
                                       const RoverOnGrids& rover, OrbitalMatch& out,
                                       const ProgressCallback& progress);

PyramidSearch MakePyramidSearch(const OrbitalTemplate& templ, const SearchSetup& setup,
                                const OrbitalMatchOptions& options, double gsd_m);

// --- Stage 3: coarse search over the rotation and scale grid. ---

struct CoarseStage {
  std::vector<double> rotations;  // The grid searched [rad].
  std::vector<double> scales;
  CoarseResult best;  // Its rotation and scale refined by a parabola between grid values.
};

// Sets out.rotation_rad, scale, rotation_solved, scale_solved, surface and surface_shift0.
std::optional<CoarseStage> SearchCoarse(const PyramidSearch& search, const SearchSetup& setup,
                                        const OrbitalPrior& prior,
                                        const OrbitalMatchOptions& options, OrbitalMatch& out,
                                        const ProgressCallback& progress);

// --- Stage 4: coarse to fine, and the peak ratio. ---

struct FineStage {
  MaskedImage warped;                         // The template at the coarse rotation and scale.
  std::vector<MaskedImage> template_pyramid;  // Of `warped`.
  double exclusion_px = 0.0;  // Runner-ups lie farther than this from the best [px].
  cv::Point coarse_peak;      // The best candidate's coarse shift [coarsest px].
  NccPeak peak;               // Its full-resolution peak.
};

// Sets out.peak_ratio.
std::optional<FineStage> RefineCoarsePeaks(const PyramidSearch& search,
                                           const OrbitalTemplate& templ, const SearchSetup& setup,
                                           const CoarseStage& coarse,
                                           const OrbitalMatchOptions& options, OrbitalMatch& out,
                                           const ProgressCallback& progress);

// --- Stage 5: rotation and scale refined at full resolution. ---

struct WarpedPeak {
  NccPeak peak;        // The full-resolution peak at the refined rotation and scale.
  MaskedImage warped;  // The template at them.
};

// Updates out.rotation_rad and out.scale.
WarpedPeak RefineWarp(const PyramidSearch& search, const OrbitalTemplate& templ,
                      const CoarseStage& coarse, const FineStage& fine, OrbitalMatch& out);

// --- Stage 6: peak measures, the correction and its covariance. ---

// Sets out.sharpness and relative_sharpness (out.correlation set to the peak's value).
void MeasureSharpness(const PyramidSearch& search, const WarpedPeak& final_peak, OrbitalMatch& out);

// Sets out.shift_px, shift_en_m, the covariances, the rotation's sigma and pivot, and
// corrected_position.
void EstimateCorrection(const WarpedPeak& final_peak, const SearchSetup& setup,
                        const RoverOnGrids& rover, const OrbitalPrior& prior,
                        const OrbitalMatchOptions& options, OrbitalMatch& out);

// --- Stage 7: the chance level and the parts test (independent: MatchOrthoToOrbital runs them
// together). ---

// The window and the template at the final warp, high-passed (high_pass.h), as both tests
// correlate them.
struct HighPassed {
  HighPassedImage window;  // setup.orbital_pyramid[0]'s.
  MaskedImage templ;
};
HighPassedImage HighPassedWindow(const SearchSetup& setup, const OrbitalTemplate& templ);

// Sets out.null, null_level, peak_z, expected_chance_peaks and false_match_probability (and the
// ring's counts where it is used).
void MeasureChanceLevel(const OrbitalImage& orbital, const OrbitalTemplate& templ,
                        const SearchSetup& setup, const CoarseStage& coarse, const FineStage& fine,
                        const WarpedPeak& final_peak, const HighPassed& hp,
                        const OrbitalMatchOptions& options, OrbitalMatch& out);

// The template's quadrants around the match (part_consistency.h); no parts with
// options.check_parts off.
PartConsistency TestParts(const FineStage& fine, const WarpedPeak& final_peak, const HighPassed& hp,
                          const OrbitalMatchOptions& options);

// --- Stage 8: the verdict. ---

// Sets out.parts_tested, part_contradiction (the parts count only where the false-match
// probability passes), reason and matched.
void Decide(const SearchSetup& setup, const FineStage& fine, const WarpedPeak& final_peak,
            const PartConsistency& parts, const OrbitalMatchOptions& options, OrbitalMatch& out);

}  // namespace areomap::internal
