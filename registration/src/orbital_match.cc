#include "areomap/registration/orbital_match.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include <tbb/parallel_invoke.h>
#include <tbb/task_group.h>

#include "areomap/map/error.h"
#include "areomap/map/report_progress.h"
#include "orbital_match_stages.h"

namespace areomap {

using internal::CheckMatchInputs;
using internal::CoarseStage;
using internal::Decide;
using internal::EstimateCorrection;
using internal::FineStage;
using internal::HighPass;
using internal::HighPassed;
using internal::HighPassedWindow;
using internal::IsIdentityWarp;
using internal::kTurn;
using internal::LocateRover;
using internal::MakePyramidSearch;
using internal::MeasureChanceLevel;
using internal::MeasureSharpness;
using internal::PyramidSearch;
using internal::RefineCoarsePeaks;
using internal::RefineWarp;
using internal::ResampleTemplate;
using internal::RoverOnGrids;
using internal::SearchCoarse;
using internal::SearchSetup;
using internal::SetUpSearch;
using internal::SimilarityMatrix;
using internal::TestParts;
using internal::WarpedPeak;

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

// The stages are in orbital_match_stages.h; each that can find no match says why in `out`.
OrbitalMatch MatchOrthoToOrbital(const OrthoImage& ortho, const OrbitalImage& orbital,
                                 const OrbitalPrior& prior, const OrbitalMatchOptions& options,
                                 const ProgressCallback& progress) {
  CheckMatchInputs(prior, options);
  OrbitalMatch out;
  out.orbital = orbital.name();
  ReportProgress(progress, 0.0, "register: resample");
  const RoverOnGrids rover = LocateRover(ortho, orbital, prior);
  out.gsd_m = rover.gsd_m;
  out.corrected_position = prior.position;
  if (!ResampleTemplate(ortho, orbital, prior, options, rover, out)) return out;

  const std::optional<SearchSetup> setup =
      SetUpSearch(orbital, prior, options, rover, out, progress);
  if (!setup) return out;
  const PyramidSearch search = MakePyramidSearch(out.templ, *setup, options, out.gsd_m);
  // The decision's high-passed window needs no peak, nor does the resampled template's high pass
  // (the final template where the search ends unwarped): both are made on another core beside
  // the search (which reports progress, from this thread only).
  HighPassed hp;
  MaskedImage hp_resampled;
  tbb::task_group beside;
  beside.run([&] {
    hp.window = HighPassedWindow(*setup, out.templ);
    hp_resampled = HighPass({out.templ.image, out.templ.mask});
  });
  std::optional<CoarseStage> coarse;
  std::optional<FineStage> fine;
  try {
    coarse = SearchCoarse(search, *setup, prior, options, out, progress);
    if (coarse)
      fine = RefineCoarsePeaks(search, out.templ, *setup, *coarse, options, out, progress);
  } catch (...) {
    beside.wait();
    throw;
  }
  beside.wait();
  if (!coarse || !fine) return out;
  const WarpedPeak final_peak = RefineWarp(search, out.templ, *coarse, *fine, out);

  out.correlation = final_peak.peak.value;
  // Independent, each writing its own fields of `out`: the chance level, the parts test (which
  // counts only if the chance level passes: Decide), and the peak's sharpness and the correction.
  hp.templ =
      IsIdentityWarp(out.rotation_rad, out.scale) ? hp_resampled : HighPass(final_peak.warped);
  PartConsistency parts;
  tbb::parallel_invoke(
      [&] {
        MeasureChanceLevel(orbital, out.templ, *setup, *coarse, *fine, final_peak, hp, options,
                           out);
      },
      [&] { parts = TestParts(*fine, final_peak, hp, options); },
      [&] {
        MeasureSharpness(search, final_peak, out);
        EstimateCorrection(final_peak, *setup, rover, prior, options, out);
      });
  Decide(*setup, *fine, final_peak, parts, options, out);
  ReportProgress(progress, 1.0, "register: done");
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
