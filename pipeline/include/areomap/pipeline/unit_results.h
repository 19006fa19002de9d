// What each unit of a mission run (mission_run.h) hands the run, typed: a unit's job returns its
// result, the run records it as the unit's unit.json "summary", and summary.json is made of the
// same records ("sites", "legs", "craters", "adjustment", "guided_registration", "products",
// "rock_tie_variance"; docs/summary-format.md), read back whole by RunSummary (run_summary.h).
// JSON only at that file boundary: ToJson writes the record the run writes (integers as
// integers), FromJson reads it back, and FromJson(ToJson()) gives the result back.
//
// Units are in the field names (_m metres, _m2 square metres, _deg degrees, _px orbital pixels,
// _percent per cent, seconds [s]). A figure the writer records as null when it is not finite
// reads back as NaN; a figure a record may lack (no truth, an older unit or summary) is
// std::nullopt (Known() tells both apart from a figure).
// Failure: FromJson throws areomap::Error naming `where` and the field's path (e.g.
// ".../unit.json: summary.registration.matched is \"x\"; expected true or false ...") when a
// field has another type than the run writes; a missing field takes its default, so that records
// written before a field existed stay readable.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/landmarks/fault_detection.h"
#include "areomap/landmarks/leg_consistency.h"
#include "areomap/landmarks/rock_extraction.h"

namespace areomap::mission_run {

// A figure that may be missing.
using Figure = std::optional<double>;

// A figure that is there and finite (not missing, not recorded as null).
inline bool Known(const Figure& figure) { return figure && std::isfinite(*figure); }

// One stereo pair of a site: its dense stereo's counts and the points kept after thinning.
struct StereoPairRecord {
  std::string instrument;
  int pair = 0, image_id = 0;
  int64_t points = 0, points_buried = 0, points_floating = 0, points_kept = 0;
  double point_spacing_m = 0.0, valid_fraction = 0.0;
  bool operator==(const StereoPairRecord&) const = default;
};

// A site's orthophoto registered on the orbital image (registration.json, RegisterSiteOrtho):
// the match (MatchJson), the prior's sigma and the number of control points written.
struct SiteRegistrationResult {
  bool skipped = false;  // The mission has no orbital image: only "status" and "reason".
  bool matched = false;
  std::string reason;  // Why not matched; empty when matched.
  int64_t control_points = 0;
  int64_t template_pixels = 0;  // Valid template pixels at full resolution.
  int search_radius_px = 0;
  Figure correlation, peak_ratio, null_highest_correlation, gsd_m, prior_sigma_m;
  Figure rotation_deg;  // When the rotation was solved.
  // The rover's correction east/north [m] and its 1-sigma, when the template overlapped.
  Figure shift_east_m, shift_north_m, sigma_east_m, sigma_north_m;
  // MatchJson's other figures, as recorded (the report lists them; the run does not read them).
  nlohmann::json other = nlohmann::json::object();

  // Matched with control points: the site is registered.
  bool Registered() const { return matched && control_points > 0; }
  bool operator==(const SiteRegistrationResult&) const = default;
  nlohmann::json ToJson() const;
  static SiteRegistrationResult FromJson(const nlohmann::json& json, const std::string& where);
};

// The site unit (sites/site_NNN/): stereo, DTM, orthophoto, registration.
struct SiteUnitResult {
  int site = -1;
  std::vector<StereoPairRecord> pairs;
  int64_t points = 0;                 // In points.ply.
  int64_t coarse_points_dropped = 0;  // Where a more precise pair saw the same ground.
  double dtm_known_area_m2 = 0.0, ortho_valid_area_m2 = 0.0;
  SiteRegistrationResult registration;
  std::map<std::string, double> seconds;  // Wall time of "stereo", "dtm", "ortho", "registration".
  bool operator==(const SiteUnitResult&) const = default;
  nlohmann::json ToJson() const;
  static SiteUnitResult FromJson(const nlohmann::json& json, const std::string& where);
};

// The leg's prior for the rock search (RunLegUnit's LegPrior): which pose and why, and the pose
// itself (site b in site a: translation [m], turn about z, down [deg]) with its sigmas.
struct LegPriorRecord {
  std::string source;  // "telemetry" or "orbital registration".
  std::string reason;  // Why telemetry; empty otherwise.
  Figure registration_minus_telemetry_m, registration_minus_telemetry_deg;
  std::optional<std::array<double, 3>> a_from_b_translation_m;  // Missing in older units.
  Figure a_from_b_turn_deg, position_sigma_m, heading_sigma_deg;
  bool operator==(const LegPriorRecord&) const = default;
};

// One matching of a leg's rocks: the outcome, the tie points, RE and the conformal fit behind the
// run's pooled variance factor, at the tie variance factor it was matched with.
struct LegPassRecord {
  std::string outcome;
  int64_t tie_points = 0, rock_matches = 0;
  Figure relative_error_percent, conformal_chi2;
  std::optional<int64_t> conformal_redundancy;
  double tie_variance_factor = 1.0;
  Figure seconds;
  bool operator==(const LegPassRecord&) const = default;
};

// The leg unit (legs/leg_NNN_MMM/): rocks of both sites, matching, fault detection, tie points;
// the legs' test against each other adds its verdict.
struct LegUnitResult {
  int site_a = -1, site_b = -1;
  double telemetry_distance_m = 0.0;
  std::optional<LegPriorRecord> prior;      // Missing in older units.
  LegPassRecord match;                      // The pass the leg stands at (flat in the JSON).
  std::optional<LegPassRecord> first_pass;  // When a second pass matched it again.
  RockExtractionSummary rocks_a, rocks_b;
  PairFaultReport faults;
  std::optional<LegConsistency> leg_test;         // After TestLegsAgainstEachOther.
  std::vector<std::string> leg_test_dropped_ids;  // Ids of the tie points the test dropped.
  bool operator==(const LegUnitResult&) const;
  nlohmann::json ToJson() const;
  static LegUnitResult FromJson(const nlohmann::json& json, const std::string& where);
};

// The craters' score against truth/craters.csv (crater_score.h's CraterMatchStats as
// CraterMatchStatsJson writes it) with the matching rule; precision and the other ratios are
// null (NaN) when undefined (nothing detected).
struct CraterScoreRecord {
  std::string rule;
  int64_t truth = 0, detected = 0, matched_truth = 0, matched_detected = 0;
  Figure precision, recall, f1, median_center_error_px;
  // The record's other figures, as written (the diameter range, median_diameter_error).
  nlohmann::json other = nlohmann::json::object();
  bool operator==(const CraterScoreRecord&) const = default;
  nlohmann::json ToJson() const;
  static CraterScoreRecord FromJson(const nlohmann::json& json, const std::string& where);
};

// The craters unit (craters/): the catalogue's figures and files, the sun azimuth used.
struct CratersUnitResult {
  bool skipped = false;  // The mission has no orbital image: only "status", "reason", seconds.
  std::string reason;
  std::string image, method;
  double pixel_size_m = 0.0, min_diameter_m = 0.0;
  int64_t craters = 0;
  std::vector<std::string> files;
  std::string sun_azimuth_source;  // "manifest", "estimated" or "none".
  Figure sun_azimuth_deg;          // Recorded as null when none.
  // The crater module's record as written (SunAzimuthEstimateJson) when estimated, else null.
  nlohmann::json sun_azimuth_estimate;
  std::optional<CraterScoreRecord> score;  // When the mission has truth/craters.csv.
  double seconds = 0.0;
  bool operator==(const CratersUnitResult&) const = default;
  nlohmann::json ToJson() const;
  static CratersUnitResult FromJson(const nlohmann::json& json, const std::string& where);
};

// AdjustTraverse's figures (traverse_adjustment.h): "adjustment" of summary.json, and each guided
// pass's repeated adjustment.
struct AdjustmentResult {
  int sites = 0;
  int64_t tie_points = 0, control_points = 0, priors = 0, heights = 0;
  double rock_tie_variance_factor = 1.0;
  int64_t rejected = 0, sites_with_priors_only = 0, redundancy = 0;
  double sigma0 = 0.0;
  bool converged = false;
  double length_m = 0.0, largest_horizontal_sigma_m = 0.0;
  Figure solve_seconds, covariance_seconds;
  std::vector<std::string> files;
  // Against the mission's truth, when it has one.
  Figure initial_end_error_m, adjusted_end_error_m, median_adjusted_leg_re;
  Figure median_adjusted_error_m, worst_adjusted_error_m;
  std::optional<int64_t> sites_within_1sigma;
  bool operator==(const AdjustmentResult&) const = default;
  nlohmann::json ToJson() const;
  static AdjustmentResult FromJson(const nlohmann::json& json, const std::string& where);
};

// The rock tie points' variance factor pooled over the legs' first passes (PoolVarianceFactor,
// localization_error.h): summary.json's "rock_tie_variance".
struct TieVarianceRecord {
  int64_t legs = 0, redundancy = 0;                // Fits pooled and their summed redundancy.
  double chi2 = 0.0;                               // Their summed chi2.
  Figure sigma0_squared, sigma0_squared_upper_95;  // nullopt (null) when nothing was pooled.
  Figure applied_factor;  // Applied by the legs' second pass; nullopt (null) when not.
  bool operator==(const TieVarianceRecord&) const = default;
  nlohmann::json ToJson() const;
  static TieVarianceRecord FromJson(const nlohmann::json& json, const std::string& where);
};

// The guided prior of a site as recorded: where the adjustment expects the rover east/north of
// its telemetry georeference [m], the orthophoto's turn [deg] and the search sigma [m].
struct GuidedPriorRecord {
  double shift_east_m = 0.0, shift_north_m = 0.0, rotation_deg = 0.0, sigma_m = 0.0;
  bool operator==(const GuidedPriorRecord&) const = default;
};

// The guided matching's settings; a finished unit is reused only when they are the run's.
struct GuidedSettings {
  int null_windows = 0;
  double max_false_match = 0.0, sigma_floor_m = 0.0;
  bool operator==(const GuidedSettings&) const = default;
};

// A guided registration unit (guided/pass_P/site_NNN/).
struct GuidedUnitResult {
  int site = -1, pass = 0;
  GuidedPriorRecord prior;
  GuidedSettings settings;
  SiteRegistrationResult registration;
  bool operator==(const GuidedUnitResult&) const = default;
  nlohmann::json ToJson() const;
  static GuidedUnitResult FromJson(const nlohmann::json& json, const std::string& where);
};

// One site a guided pass matched again.
struct GuidedAttemptRecord {
  int site = -1;
  GuidedPriorRecord prior;
  bool matched = false;
  std::string reason;
  Figure correlation, null_highest_correlation;  // Recorded as null when missing.
  int search_radius_px = 0;
  int64_t control_points = 0;
  bool turn_at_edge = false;  // Matched again because its first turn was at the grid's edge.
  bool operator==(const GuidedAttemptRecord&) const = default;
};

struct GuidedPassRecord {
  int pass = 0;
  std::vector<GuidedAttemptRecord> attempted;
  std::vector<int> registered;  // Sites that registered in this pass.
  std::vector<int> replaced;    // Registered sites matched again (turn at the grid's edge).
  std::optional<AdjustmentResult> adjustment;  // Repeated when a site registered or was replaced.
  bool operator==(const GuidedPassRecord&) const = default;
};

// The guided passes (RunGuidedPasses): summary.json's "guided_registration".
struct GuidedPassesResult {
  std::vector<int> registered_first_pass;
  AdjustmentResult first_adjustment;
  std::vector<GuidedPassRecord> passes;
  bool operator==(const GuidedPassesResult&) const = default;
  nlohmann::json ToJson() const;
  static GuidedPassesResult FromJson(const nlohmann::json& json, const std::string& where);
};

// Traverse DTM minus the orbital DTM over the cells both know [m] (only "cells" when none).
struct TraverseDifference {
  int64_t cells = 0;
  Figure mean_m, rms_m, stddev_m, median_abs_m;
  bool operator==(const TraverseDifference&) const = default;
};

// Orthomosaic against the orbital image: Pearson correlation over the cells both cover.
struct TraverseCorrelation {
  int64_t cells = 0;
  Figure correlation;  // Missing with fewer than two cells.
  bool operator==(const TraverseCorrelation&) const = default;
};

// The products unit (products/): traverse DTM and orthomosaic, compared with the orbital data.
struct ProductsUnitResult {
  double posting_m = 0.0;
  int width = 0, height = 0;
  double dtm_known_area_m2 = 0.0, ortho_valid_area_m2 = 0.0;
  std::vector<std::string> files;
  // The adjusted poses the products were made with (x, y, z [m], qw, qx, qy, qz), one per site;
  // in unit.json only (summary.json leaves them out: empty).
  std::vector<std::array<double, 7>> poses;
  std::optional<std::string> orbital_dtm, orbital_image;  // File names, when the mission has them.
  std::optional<TraverseDifference> dtm_minus_orbital_adjusted, dtm_minus_orbital_telemetry;
  std::optional<TraverseCorrelation> ortho_vs_orbital_adjusted, ortho_vs_orbital_telemetry;
  std::map<std::string, double> seconds;  // Wall time of "dtm", "orthomosaic", "comparison".
  bool operator==(const ProductsUnitResult&) const = default;
  nlohmann::json ToJson() const;
  static ProductsUnitResult FromJson(const nlohmann::json& json, const std::string& where);
};

}  // namespace areomap::mission_run
