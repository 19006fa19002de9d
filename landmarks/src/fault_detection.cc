#include "areomap/landmarks/fault_detection.h"

#include <cstdio>

#include <nlohmann/json.hpp>

#include "areomap/map/error.h"

namespace areomap {

void FaultDetectionOptions::Check() const {
  RequireOption(max_traverse_m > 0.0, "FaultDetectionOptions.max_traverse_m", "> 0 m");
  RequireOption(min_peaks_per_site >= 0, "FaultDetectionOptions.min_peaks_per_site", ">= 0");
  RequireOption(min_correlation >= -1.0 && min_correlation <= 1.0,
                "FaultDetectionOptions.min_correlation", "between -1 and 1");
  RequireOption(max_vertical_disparity_px >= 0.0, "FaultDetectionOptions.max_vertical_disparity_px",
                ">= 0 px");
  RequireOption(max_peak_range_m > 0.0, "FaultDetectionOptions.max_peak_range_m", "> 0 m");
  RequireOption(min_peak_to_plane_m >= 0.0, "FaultDetectionOptions.min_peak_to_plane_m", ">= 0 m");
  RequireOption(min_window_points >= 1, "FaultDetectionOptions.min_window_points", ">= 1");
  RequireOption(min_pair_distance_ratio >= 0.0 && min_pair_distance_ratio <= 1.0,
                "FaultDetectionOptions.min_pair_distance_ratio", "between 0 and 1");
  RequireOption(min_rock_distance_ratio >= 0.0 && min_rock_distance_ratio <= 1.0,
                "FaultDetectionOptions.min_rock_distance_ratio", "between 0 and 1");
  RequireOption(min_surface_points >= 3, "FaultDetectionOptions.min_surface_points",
                ">= 3 (a surface needs 3 points)");
  RequireOption(max_model_size_m > 0.0, "FaultDetectionOptions.max_model_size_m", "> 0 m");
  RequireOption(max_normal_angle_deg > 0.0 && max_normal_angle_deg <= 90.0,
                "FaultDetectionOptions.max_normal_angle_deg", "in (0, 90] degrees");
  RequireOption(min_tie_points >= 2, "FaultDetectionOptions.min_tie_points",
                ">= 2 (the conformal transform needs 2)");
  RequireOption(max_relative_error_percent > 0.0,
                "FaultDetectionOptions.max_relative_error_percent", "> 0 %");
}

std::string ToString(FaultVerdict verdict) {
  switch (verdict) {
    case FaultVerdict::kPass:
      return "pass";
    case FaultVerdict::kFail:
      return "fail";
    case FaultVerdict::kNotEvaluated:
      return "not evaluated";
  }
  return "unknown";
}

std::string ToString(PairOutcome outcome) {
  switch (outcome) {
    case PairOutcome::kMatched:
      return "matched";
    case PairOutcome::kExcludedByPreScreening:
      return "excluded by pre-screening";
    case PairOutcome::kExcludedByFaultDetection:
      return "excluded by fault detection";
  }
  return "unknown";
}

void PairFaultReport::Add(FaultCheck check) {
  if (check.ExcludesPair()) {
    const bool pre_screening =
        check.module.rfind("I ", 0) == 0 || check.module.rfind("II ", 0) == 0;
    if (pre_screening) {
      outcome = PairOutcome::kExcludedByPreScreening;
    } else if (outcome == PairOutcome::kMatched) {
      outcome = PairOutcome::kExcludedByFaultDetection;
    }
  }
  checks.push_back(std::move(check));
}

const FaultCheck* PairFaultReport::Find(std::string_view rule) const {
  for (const FaultCheck& c : checks) {
    if (c.rule == rule) return &c;
  }
  return nullptr;
}

nlohmann::json ToJson(const FaultCheck& c) {
  return {{"module", c.module},
          {"rule", c.rule},
          {"value", c.value},
          {"threshold", c.threshold},
          {"unit", c.unit},
          {"verdict", ToString(c.verdict)},
          {"excludes_pair", c.excludes_pair}};
}

nlohmann::json PairFaultReport::ToJson() const {
  nlohmann::json rules = nlohmann::json::array();
  for (const FaultCheck& c : checks) rules.push_back(areomap::ToJson(c));
  return {{"site_a", site_a},
          {"site_b", site_b},
          {"outcome", ToString(outcome)},
          {"outcome_code", static_cast<int>(outcome)},
          {"rules", rules}};
}

std::string PairFaultReport::ToText() const {
  std::string text = "sites " + std::to_string(site_a) + "-" + std::to_string(site_b) + ": " +
                     ToString(outcome) + "\n";
  for (const FaultCheck& c : checks) {
    char line[256];
    std::snprintf(line, sizeof(line), "  %-16s %-48s %10.3f %10.3f %-6s %s%s\n", c.module.c_str(),
                  c.rule.c_str(), c.value, c.threshold, c.unit.c_str(), ToString(c.verdict).c_str(),
                  c.ExcludesPair() ? " (excludes pair)" : "");
    text += line;
  }
  return text;
}

FaultCheck MaxCheck(std::string module, std::string rule, double value, double threshold,
                    std::string unit, bool excludes_pair) {
  return {std::move(module),
          std::move(rule),
          value,
          threshold,
          std::move(unit),
          value <= threshold ? FaultVerdict::kPass : FaultVerdict::kFail,
          excludes_pair};
}

FaultCheck MinCheck(std::string module, std::string rule, double value, double threshold,
                    std::string unit, bool excludes_pair) {
  return {std::move(module),
          std::move(rule),
          value,
          threshold,
          std::move(unit),
          value >= threshold ? FaultVerdict::kPass : FaultVerdict::kFail,
          excludes_pair};
}

FaultCheck RockCount(std::string module, std::string rule, int excluded, double threshold,
                     std::string unit) {
  return {std::move(module),
          std::move(rule),
          static_cast<double>(excluded),
          threshold,
          std::move(unit),
          excluded > 0 ? FaultVerdict::kFail : FaultVerdict::kPass,
          false};
}

}  // namespace areomap
