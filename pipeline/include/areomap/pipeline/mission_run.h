// The end-to-end job (`areomap run`): a mission folder (mission_manifest.h) in, a rover traverse
// anchored in Mars body-fixed coordinates out, with every intermediate product on disk.
//
// Work units and their folders under `out_dir` (DESIGN.md: units whose results are files):
//   sites/site_NNN/   one per site: dense stereo of every pair -> points.ply (site frame),
//                     DTM and orthophoto GeoTIFFs on the mission map (telemetry georeference),
//                     orbital registration of the orthophoto -> registration.json, the
//                     correlation surface PNG and control_points.json (BA input format)
//   legs/leg_NNN_MMM/ one per consecutive pair of sites: rock extraction at both sites, cross-site
//                     matching with fault detection -> tie_points.json, faults.json; after the
//                     second pass (MissionRunOptions::rock_variance_pass) its matching, the
//                     first pass's figures in unit.json's "first_pass"
//   craters/          crater detection on the first orbital image (CSV, JSON, overlay PNG)
//   guided/pass_P/site_NNN/  guided re-registration of a site that did not register, around
//                     its pose from the previous adjustment (MissionRunOptions::guided_passes):
//                     registration.json, correlation_surface.png, control_points.json; the
//                     adjustment is then repeated with them (summary.json "guided_registration")
//   adjustment/       network.json (sites, telemetry priors, truth), the bundle adjustment and
//                     the anchored traverse: sites.csv, legs.csv, traverse.gpkg, traverse_map.png;
//                     rock_ties/leg_NNN_MMM.json: the tie points of a leg that the legs' test
//                     (MissionRunOptions::leg_test) changed, read instead of the leg's own
//   products/         DTM (traverse_dtm.tif) and orthomosaic (traverse_ortho.tif) of the whole
//                     traverse with the adjusted poses, PNG thumbnails, and their differences
//                     from the orbital DTM and image with adjusted and with telemetry poses
//   summary.json      key figures, wall time per stage ("stage_seconds"), the rock tie
//                     points' a-posteriori variance factor pooled over the legs' conformal fits
//                     ("rock_tie_variance", PoolVarianceFactor, and the factor the second pass
//                     applied, "applied_factor"); schema in docs/summary-format.md, read by
//                     RunSummary (run_summary.h); report.html is written from the folder by
//                     WriteRunReport.
// A unit is finished when its `unit.json` exists (written last, atomically) and records the
// same fingerprint as this run: the mission folder, the options, and the path, size and
// modification time of every file the manifest names (products/: and the same adjusted poses),
// and every file the unit wrote is still there (a deleted points.ply makes its site run again);
// finished units are skipped, so an interrupted run resumes where it stopped, and any changed
// input file makes every unit run again. Site units run in parallel (TBB).
//
// Frames: site frames are MER SITE_FRAMEs (x north, y east, z down [m]); the traverse frame is
// site 0's; the mission map is equirectangular on the local-radius sphere at the mission origin
// (the orbital products' projection), heights above the body's ellipsoid.
// Failure: a bad manifest fails before any work (ReadMissionManifest); a unit that fails throws
// areomap::Error naming the site or leg, leaving the finished units in place.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/adjustment/bundle_adjustment.h"
#include "areomap/crater/crater_detector.h"
#include "areomap/landmarks/leg_consistency.h"
#include "areomap/landmarks/localization_error.h"
#include "areomap/landmarks/rock_extraction.h"
#include "areomap/landmarks/rock_matching.h"
#include "areomap/map/dense_stereo.h"
#include "areomap/map/dtm.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/mosaic.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/progress.h"
#include "areomap/map/rigid3d.h"
#include "areomap/pipeline/run_summary.h"
#include "areomap/registration/orbital_match.h"
#include "areomap/registration/orbital_report.h"

namespace areomap {

struct MissionRunOptions {
  DenseStereoOptions stereo;  // Per pair; max_range_m 30 (Table 4.5).
  // Stereo points kept about this far apart on the ground (ThinToGroundSpacing): near the mast a
  // Navcam pixel covers ~2 mm, far finer than DTM postings or rock modeling need [m].
  double point_spacing_m = 0.02;
  // Pairs whose pixels are finer than fine_pair_max_ifov_mrad (Pancam: 0.28 mrad/px; Navcam
  // 0.76, Hazcam 2.1) keep their points fine_pair_point_spacing_m apart instead: fine points
  // sharpen precise pairs' rock models but turn Navcam noise into peaks (docs/rocks.md)
  // [m, mrad/px].
  double fine_pair_point_spacing_m = 0.01;
  double fine_pair_max_ifov_mrad = 0.5;
  // The spacing for a pair whose rectified focal length is `focal_px`.
  double PointSpacingFor(double focal_px) const {
    return 1000.0 / focal_px < fine_pair_max_ifov_mrad ? fine_pair_point_spacing_m
                                                       : point_spacing_m;
  }
  // Where a site's pairs see the same ground with unlike precision (Pancam over Navcam), only
  // the precise pairs' points are kept there (KeepMostPreciseSource); false keeps every point.
  bool prefer_precise_pairs = true;
  PreciseSourceOptions precise_pairs;
  DtmOptions dtm;  // 0.1 m posting.
  OrthoOptions ortho;
  // Heading drift turns a site's orthophoto on the map (a few degrees after a few legs), so the
  // orbital search also tries rotations of up to +-5 degrees.
  OrbitalMatchOptions match = [] {
    OrbitalMatchOptions o;
    o.max_rotation_deg = 5.0;
    return o;
  }();
  ControlPointOptions control;
  // Guided re-registration: after the first adjustment, each site whose orthophoto did not
  // register (but had enough valid template pixels) is matched again with the search centred on its
  // adjusted position and heading and a window of match.search_sigmas x its adjusted horizontal 1
  // sigma (at least guided_sigma_floor_m [m]), with the chance-level test over guided_null_windows
  // windows (OrbitalMatchOptions::null_windows); its control points join a re-adjustment. Repeated
  // while new sites register, at most guided_passes times (0 = off). The first guided pass also
  // re-matches sites whose first match turned the orthophoto by the most the rotation grid
  // allows (max_rotation_deg: the true turn may lie beyond), a guided match replacing their
  // control points. Recorded in the guided units themselves, not in the options fingerprint:
  // changing them keeps the site units.
  int guided_passes = 3;
  double guided_sigma_floor_m = 0.5;
  int guided_null_windows = 48;
  // Orbital prior: 1 sigma of the telemetry position = floor + fraction x distance driven from
  // site 0 (dead reckoning drifts with distance; ~10 % at Silver Lake, ch. 4).
  double prior_sigma_floor_m = 2.0;
  double prior_sigma_per_m = 0.1;
  RockExtractionOptions rocks;
  RockMatchingOptions matching;
  // The legs' tie points tested against each other before the adjustment (leg_consistency.h): a
  // leg whose conformal fit is less precise than the other legs' by more than the F quantile at
  // 1 - leg_test_alpha loses its worst tie points, or is excluded. Its min_tie_points and
  // max_residual_chi2 are matching's; false skips the test. Applied when the legs are gathered,
  // not in the options fingerprint: changing it keeps the leg units.
  bool leg_test = true;
  double leg_test_alpha = 0.001;
  LegConsistencyOptions LegTestOptions() const;  // The alpha above, matching's other figures.
  // A second pass over the legs with the rock tie points' own precision, since eq. 4.3's
  // covariances can be off by a factor either way (docs/rocks.md) and RE (eq. 4.9) follows
  // them. The first pass's conformal fits, pooled (PoolVarianceFactor), estimate the factor;
  // when their pooled redundancy is at least rock_variance_pass_min_redundancy, every leg is
  // matched again with RockMatchingOptions::tie_variance_factor at its one-sided 95 % upper
  // bound (conformal fit, outlier test, RE and the written tie points). The adjustment keeps
  // the a-priori covariances. Applied when the legs are gathered, not in the options
  // fingerprint; a leg unit records the factor it was matched with and its first pass
  // ("first_pass"), and is matched again only when the factor changes.
  bool rock_variance_pass = true;
  int rock_variance_pass_min_redundancy = 20;
  // The factor the second pass applies given the first pass's pooled fits; nullopt when the
  // pass is off or the pooled redundancy is too small (or the pooled bound not finite).
  std::optional<double> RockVariancePassFactor(const PooledVarianceFactor& first_pass) const;
  BundleOptions bundle;
  // Telemetry pose priors per leg (DeadReckoningCovariance): relative length error and heading
  // drift per leg, 1 sigma. Defaults to the mission's telemetry model when it states one.
  double leg_scale_sigma = 0.05;
  double leg_heading_sigma_deg = 2.0;
  bool detect_craters = true;
  // Craters: rims from this diameter up [m] on the orbital image; the detector's other options.
  double crater_min_diameter_m = 4.0;
  CraterDetectorOptions craters;
  // Whole-traverse DTM and orthomosaic (products/) with the adjusted poses: posting [m] (the
  // traverse covers far more ground than a site; HiRISE's 0.25 m keeps it comparable with the
  // orbital image) and the mosaic's seam feathering.
  bool traverse_products = true;
  double traverse_posting_m = 0.25;
  MosaicOptions mosaic;
  void Check() const;  // Throws areomap::Error naming the field.
  // The options as JSON: recorded in every unit.json; a change invalidates finished units.
  nlohmann::json ToJson() const;
};

struct MissionRunSummary {
  RunSummary record;    // The run's summary, typed (run_summary.h).
  nlohmann::json json;  // record.ToJson(): what summary.json holds (also the report's source).
  int sites_computed = 0;
  int sites_reused = 0;
  int legs_computed = 0;
  int legs_reused = 0;
  int legs_rematched = 0;  // Matched again by the second pass (rock_variance_pass).
};

// Guided re-registration of a site after an adjustment (MissionRunOptions::guided_passes): where
// the adjustment moves the site from its telemetry pose, as an orbital search prior. Site
// frames are level, x north, y east, z down; the covariance is the adjusted pose's, over
// (rotation vector [rad], translation [m]) as in BundleResult.
struct GuidedPrior {
  Eigen::Vector2d shift_en_m = Eigen::Vector2d::Zero();  // Adjusted - telemetry, east, north [m].
  double rotation_rad = 0.0;  // The adjusted turn, counter-clockwise on the map [rad].
  double sigma_m = 0.0;       // Largest horizontal 1 sigma, at least the floor [m].
};
// Throws areomap::Error if a pose or the covariance is not finite.
GuidedPrior GuidedPriorFromPoses(const Rigid3d& telemetry_traverse_from_site,
                                 const Rigid3d& adjusted_traverse_from_site,
                                 const Matrix6d& adjusted_covariance, double sigma_floor_m);

// Runs (or resumes) the whole job. `progress` sees one fraction for the whole run.
MissionRunSummary RunMission(const MissionManifest& mission, const std::filesystem::path& out_dir,
                             const MissionRunOptions& options,
                             const ProgressCallback& progress = nullptr);

// The job `areomap run MISSION --out DIR` is, as the CLI and the Python module call it: checks
// `options`, takes `out_dir` under the output-folder policy (output_folder.h: in place, the run's
// own folders and files, a lock; `overwrite` replaces foreign files that carry an output's name),
// reads the manifest of the mission folder `mission` (every file it names checked before any
// work), runs or resumes the mission (RunMission), writes out_dir/summary.json (the summary's
// JSON with "command": "run") and out_dir/report.html, and records the outputs. Throws
// areomap::Error as those steps do (nothing is recorded then; finished units stay for a resume).
MissionRunSummary RunMissionFolder(const std::filesystem::path& mission,
                                   const std::filesystem::path& out_dir,
                                   const MissionRunOptions& options, bool overwrite = false,
                                   const ProgressCallback& progress = nullptr);

}  // namespace areomap
