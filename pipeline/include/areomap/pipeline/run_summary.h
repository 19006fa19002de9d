// summary.json of `areomap run`, typed: the figures its readers (the HTML report, the CLI's
// closing lines, scripts through docs/summary-format.md) take from it. RunMission writes the
// file; RunSummary::FromJson is the one place that reads it back, so the schema lives here and in
// docs/summary-format.md instead of in string keys spread over the readers.
//
// Units are in the field names (_m metres, _m2 square metres, _deg degrees, _px orbital pixels,
// _percent per cent). A figure a run may lack (no truth, no orbital DTM, craters or products off,
// a leg without tie points) is std::nullopt; summary.json holds it as null or leaves it out.
//
// Failure: FromJson throws areomap::Error naming `source` and the field (e.g.
// "summary.json: sites[2].registration.correlation is \"x\"; expected a number") when a field has
// another type than RunMission writes, or "sites" / "legs" is not an array of objects.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace areomap {

// A figure that may be missing.
using OptionalNumber = std::optional<double>;

// A site's orbital registration (registration.json's summary).
struct SiteRegistrationSummary {
  bool matched = false;
  std::string reason;  // Why not matched; empty when matched.
  OptionalNumber correlation, peak_ratio, control_points;
  // Every figure of registration.json as recorded, the four above included (the report lists
  // them all).
  nlohmann::json record = nlohmann::json::object();
  bool operator==(const SiteRegistrationSummary&) const = default;
};

struct SiteSummary {
  int site = -1;
  OptionalNumber points, dtm_known_area_m2, ortho_valid_area_m2;
  SiteRegistrationSummary registration;
  bool operator==(const SiteSummary&) const = default;
};

// One rule of a leg's fault detection (Table 4.5).
struct FaultRuleSummary {
  std::string module, rule, unit, verdict;
  OptionalNumber value, threshold;
  bool operator==(const FaultRuleSummary&) const = default;
};

// The legs' test against each other (leg_consistency.h).
struct LegTestSummary {
  bool tested = false;
  std::vector<int> dropped;  // Indices of the leg's tie points the test dropped.
  OptionalNumber first_f_statistic, f_threshold;
  bool operator==(const LegTestSummary&) const = default;
};

// A leg's first pass, when a second pass matched it again with the pooled variance factor.
struct LegFirstPassSummary {
  std::string outcome;
  OptionalNumber tie_points, relative_error_percent;
  bool operator==(const LegFirstPassSummary&) const = default;
};

struct LegSummary {
  int site_a = -1, site_b = -1;
  std::string outcome;
  int tie_points = 0;
  OptionalNumber relative_error_percent, telemetry_distance_m, tie_variance_factor;
  std::optional<LegFirstPassSummary> first_pass;
  LegTestSummary leg_test;
  std::vector<FaultRuleSummary> rules;
  bool operator==(const LegSummary&) const = default;
};

// The bundle adjustment's figures; the *_error_* ones and sites_within_1sigma need truth.
struct AdjustmentSummary {
  OptionalNumber length_m, sigma0, tie_points, control_points, rejected, sites;
  OptionalNumber initial_end_error_m, adjusted_end_error_m, median_adjusted_leg_re;
  OptionalNumber largest_horizontal_sigma_m, median_adjusted_error_m, worst_adjusted_error_m;
  OptionalNumber sites_within_1sigma;
  bool operator==(const AdjustmentSummary&) const = default;
};

// The rock tie points' variance factor pooled over the legs' first passes.
struct TieVarianceSummary {
  OptionalNumber sigma0_squared, sigma0_squared_upper_95, legs, redundancy;
  OptionalNumber applied_factor;  // Applied by the legs' second pass; nullopt when not.
  bool operator==(const TieVarianceSummary&) const = default;
};

struct GuidedAttemptSummary {
  int site = -1;
  bool matched = false;
  std::string reason;
  OptionalNumber correlation, null_highest_correlation, control_points, search_radius_px;
  OptionalNumber prior_rotation_deg, prior_sigma_m;  // The guided prior.
  bool operator==(const GuidedAttemptSummary&) const = default;
};

struct GuidedPassSummary {
  int pass = 0;
  std::vector<GuidedAttemptSummary> attempted;
  std::vector<int> registered;  // Sites that registered in this pass.
  std::vector<int> replaced;    // Sites matched again whose first turn was at the search's edge.
  bool operator==(const GuidedPassSummary&) const = default;
};

// Guided re-registration after the first adjustment; nullopt first pass when it did not run.
struct GuidedSummary {
  std::optional<std::vector<int>> registered_first_pass;
  std::vector<GuidedPassSummary> passes;
  bool operator==(const GuidedSummary&) const = default;
};

// Traverse product minus the orbital DTM over the cells both know.
struct DifferenceSummary {
  OptionalNumber cells, mean_m, stddev_m, rms_m, median_abs_m;
  bool operator==(const DifferenceSummary&) const = default;
};

struct ProductsSummary {
  OptionalNumber posting_m, dtm_known_area_m2, ortho_valid_area_m2;
  std::optional<DifferenceSummary> dtm_minus_orbital_adjusted, dtm_minus_orbital_telemetry;
  // Orthomosaic against the orbital image: correlation over the cells both cover.
  std::optional<OptionalNumber> ortho_vs_orbital_adjusted, ortho_vs_orbital_telemetry;
  bool operator==(const ProductsSummary&) const = default;
};

struct CraterScoreSummary {
  std::string rule;
  OptionalNumber truth, matched_truth, precision, recall, median_center_error_px;
  bool operator==(const CraterScoreSummary&) const = default;
};

struct CratersSummary {
  OptionalNumber craters, min_diameter_m;
  std::optional<CraterScoreSummary> score;  // Against the mission's truth, when it has one.
  bool operator==(const CratersSummary&) const = default;
};

// Which units this invocation computed and which it found finished.
struct UnitsSummary {
  int sites_computed = 0, sites_reused = 0, legs_computed = 0, legs_reused = 0;
  int legs_rematched = 0;
  bool operator==(const UnitsSummary&) const = default;
};

struct RunSummary {
  std::string name;        // The mission's.
  OptionalNumber seconds;  // Wall time of the invocation.
  std::vector<SiteSummary> sites;
  std::vector<LegSummary> legs;
  AdjustmentSummary adjustment;
  TieVarianceSummary tie_variance;  // "rock_tie_variance".
  GuidedSummary guided;             // "guided_registration".
  std::optional<ProductsSummary> products;
  std::optional<CratersSummary> craters;
  std::optional<UnitsSummary> units;
  // Wall time per stage [s]: of this invocation, and as recorded when the units were computed.
  std::map<std::string, double> stage_seconds, computed_seconds;
  bool operator==(const RunSummary&) const = default;

  // `source` names the file in error messages.
  static RunSummary FromJson(const nlohmann::json& json, const std::string& source);
  // The fields above under summary.json's names (nullopt figures left out): FromJson of it
  // gives this summary back.
  nlohmann::json ToJson() const;
};

// out_dir/summary.json read by RunSummary::FromJson; throws areomap::Error naming the folder
// when there is none, or the file when it is not JSON or not a run's (no "sites" and "legs").
RunSummary ReadRunSummary(const std::filesystem::path& out_dir);

}  // namespace areomap
