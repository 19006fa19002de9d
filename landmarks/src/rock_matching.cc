// Cross-site rock matching (ch. 3.2) with the fault detection rules of Table 4.5: the options,
// the per-rock rules and costs, and MatchSitePair as the sequence of its stages
// (rock_matching_stages.h).
#include "areomap/landmarks/rock_matching.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "areomap/landmarks/localization_error.h"
#include "areomap/map/error.h"
#include "rock_matching_geometry.h"
#include "rock_matching_stages.h"

namespace areomap {

using rock_matching_internal::AddPairLevelChecks;
using rock_matching_internal::AddPreScreeningChecks;
using rock_matching_internal::AmbiguityTest;
using rock_matching_internal::CandidateSet;
using rock_matching_internal::CombinedMatches;
using rock_matching_internal::CombineMethods;
using rock_matching_internal::DropResidualOutliers;
using rock_matching_internal::EligibleRocks;
using rock_matching_internal::FateLog;
using rock_matching_internal::FitGlobalPattern;
using rock_matching_internal::GenerateCandidates;
using rock_matching_internal::GlobalPattern;
using rock_matching_internal::KeepLowestCostPerRockOfB;
using rock_matching_internal::kRadToDeg;
using rock_matching_internal::LargestHorizontalSigma;
using rock_matching_internal::MakeTiePoint;
using rock_matching_internal::RelativeDifference;
using rock_matching_internal::RocksOfBInA;
using rock_matching_internal::SelectEligibleRocks;
using rock_matching_internal::SelectSignificantRocks;
using rock_matching_internal::SignificantRocks;
using rock_matching_internal::SitePair;
using rock_matching_internal::UniqueMatches;

std::string ToString(RockRule rule) {
  switch (rule) {
    case RockRule::kEligible:
      return "eligible";
    case RockRule::kBeyondRange:
      return "beyond range";
    case RockRule::kTooLow:
      return "too low";
    case RockRule::kFewPoints:
      return "few surface points / no model";
    case RockRule::kImplausible:
      return "implausible model";
    case RockRule::kLowRatio:
      return "distance ratio";
    case RockRule::kImprecise:
      return "peak sigma";
  }
  return "?";
}

void CheckModelsCoverHeightRule(const RockExtractionOptions& extraction,
                                const RockMatchingOptions& matching) {
  RequireOption(
      extraction.model_min_height_m <= matching.fault_detection.min_peak_to_plane_m,
      "RockExtractionOptions.model_min_height_m",
      "at most FaultDetectionOptions.min_peak_to_plane_m (rocks that pass the height rule "
      "need a model)");
}

RockRule CheckRockRules(const ExtractedRock& r, const Eigen::Vector3d& own,
                        const Eigen::Vector3d& other, const RockMatchingOptions& options) {
  const FaultDetectionOptions& fd = options.fault_detection;
  if ((r.peak - own).head<2>().norm() > fd.max_peak_range_m) return RockRule::kBeyondRange;
  if (r.height_m < fd.min_peak_to_plane_m) return RockRule::kTooLow;
  if (static_cast<int>(r.surface_indices.size()) < fd.min_surface_points || !r.modeled()) {
    return RockRule::kFewPoints;
  }
  if (r.best_model()->parameters.height > fd.max_model_size_m ||
      r.best_model()->parameters.MeanRadius() > fd.max_model_size_m) {
    return RockRule::kImplausible;
  }
  if (DistanceRatio(r.peak, own, other) < fd.min_rock_distance_ratio) return RockRule::kLowRatio;
  if (LargestHorizontalSigma(r) > options.max_peak_sigma_m) return RockRule::kImprecise;
  return RockRule::kEligible;
}

void RockMatchingOptions::Check() const {
  RequireOption(significant_cell_m > 0.0, "RockMatchingOptions.significant_cell_m", "> 0 m");
  RequireOption(significant_per_cell >= 1, "RockMatchingOptions.significant_per_cell", ">= 1");
  RequireOption(search_radius_m > 0.0, "RockMatchingOptions.search_radius_m", "> 0 m");
  RequireOption(pattern_tolerance_m > 0.0, "RockMatchingOptions.pattern_tolerance_m", "> 0 m");
  RequireOption(max_vector_deviation_m > 0.0, "RockMatchingOptions.max_vector_deviation_m",
                "> 0 m");
  RequireOption(prior_heading_sigma_deg >= 0.0, "RockMatchingOptions.prior_heading_sigma_deg",
                ">= 0 degrees");
  RequireOption(max_vector_chi2 > 0.0, "RockMatchingOptions.max_vector_chi2", "> 0");
  RequireOption(max_residual_chi2 > 0.0, "RockMatchingOptions.max_residual_chi2", "> 0");
  RequireOption(std::isfinite(tie_variance_factor) && tie_variance_factor > 0.0,
                "RockMatchingOptions.tie_variance_factor", "finite and > 0");
  RequireOption(peak_definition_sigma_m >= 0.0, "RockMatchingOptions.peak_definition_sigma_m",
                ">= 0 m");
  RequireOption(cost_height_weight >= 0.0 && cost_radius_weight >= 0.0 && cost_area_weight >= 0.0 &&
                    cost_height_weight + cost_radius_weight + cost_area_weight > 0.0,
                "RockMatchingOptions.cost_height_weight", "non-negative weights, not all zero");
  RequireOption(max_model_cost > 0.0, "RockMatchingOptions.max_model_cost", "> 0");
  RequireOption(min_shape_points >= 0, "RockMatchingOptions.min_shape_points", ">= 0");
  RequireOption(ambiguity_sigmas >= 0.0, "RockMatchingOptions.ambiguity_sigmas", ">= 0");
  RequireOption(ambiguity_min_height_m >= 0.0, "RockMatchingOptions.ambiguity_min_height_m",
                ">= 0 m");
  RequireOption(ambiguity_similar_min_height_m >= 0.0,
                "RockMatchingOptions.ambiguity_similar_min_height_m", ">= 0 m");
  RequireOption(ambiguity_similar_height_difference >= 0.0,
                "RockMatchingOptions.ambiguity_similar_height_difference", ">= 0");
  RequireOption(max_peak_sigma_m > 0.0, "RockMatchingOptions.max_peak_sigma_m", "> 0 m");
  RequireOption(low_rock_max_peak_sigma_m > 0.0, "RockMatchingOptions.low_rock_max_peak_sigma_m",
                "> 0 m");
  RequireOption(low_pair_max_height_m >= 0.0, "RockMatchingOptions.low_pair_max_height_m",
                ">= 0 m");
  RequireOption(pattern_vouch_deviation_m >= 0.0, "RockMatchingOptions.pattern_vouch_deviation_m",
                ">= 0 m");
  RequireOption(pattern_vouch_votes >= 1, "RockMatchingOptions.pattern_vouch_votes", ">= 1");
  RequireOption(consensus_turn_trim_m > 0.0, "RockMatchingOptions.consensus_turn_trim_m", "> 0 m");
  fault_detection.Check();
}

double ModelMatchCost(const RockModelParameters& p, const RockModelParameters& q,
                      const RockMatchingOptions& options) {
  return options.cost_height_weight * RelativeDifference(p.height, q.height) +
         options.cost_radius_weight * RelativeDifference(p.MeanRadius(), q.MeanRadius()) +
         options.cost_area_weight * RelativeDifference(p.SurfaceAreaExact(), q.SurfaceAreaExact());
}

bool ModelsRestOnShapePoints(const ExtractedRock& p, const ExtractedRock& q,
                             const RockMatchingOptions& options) {
  return std::min(p.surface_indices.size(), q.surface_indices.size()) >=
         static_cast<size_t>(options.min_shape_points);
}

double PairCost(const ExtractedRock& p, const ExtractedRock& q,
                const RockMatchingOptions& options) {
  if (options.compare_models && ModelsRestOnShapePoints(p, q, options)) {
    return ModelMatchCost(p.best_model()->parameters, q.best_model()->parameters, options);
  }
  const double difference = RelativeDifference(p.height_m, q.height_m);
  const double alike = options.ambiguity_similar_height_difference;
  if (alike <= 0.0) return difference > 0.0 ? std::numeric_limits<double>::infinity() : 0.0;
  return options.max_model_cost * difference / alike;
}

void RockMatchingPrior::Check() const {
  RequireOption(position_sigma_m >= 0.0, "RockMatchingPrior.position_sigma_m",
                ">= 0 m (infinity: unknown)");
  RequireOption(std::isfinite(heading_sigma_deg) && heading_sigma_deg >= 0.0,
                "RockMatchingPrior.heading_sigma_deg", ">= 0 degrees");
  RequireOption(a_from_b.translation.allFinite() && a_from_b.rotation.coeffs().allFinite(),
                "RockMatchingPrior.a_from_b", "a finite pose");
}

SitePairMatch MatchSitePair(const SiteRocks& a, const SiteRocks& b, const Rigid3d& a_from_b_prior,
                            const RockMatchingOptions& options,
                            const std::optional<StereoQuality>& stereo) {
  RockMatchingPrior prior;
  prior.a_from_b = a_from_b_prior;
  prior.position_sigma_m = std::numeric_limits<double>::infinity();
  prior.heading_sigma_deg = options.prior_heading_sigma_deg;
  return MatchSitePair(a, b, prior, options, stereo);
}

SitePairMatch MatchSitePair(const SiteRocks& a, const SiteRocks& b, const RockMatchingPrior& prior,
                            const RockMatchingOptions& options,
                            const std::optional<StereoQuality>& stereo) {
  options.Check();
  prior.Check();
  const SitePair pair(a, b, prior, options);
  const FaultDetectionOptions& fd = options.fault_detection;
  SitePairMatch result;
  PairFaultReport& report = result.report;
  report.site_a = a.site;
  report.site_b = b.site;

  // I and II: pre-screening.
  AddPreScreeningChecks(pair, stereo, &report);
  if (report.outcome == PairOutcome::kExcludedByPreScreening) return result;

  // III: per-rock rules, then the significant rocks of a (the highest unambiguous ones per grid
  // cell, in the overlap).
  const EligibleRocks eligible = SelectEligibleRocks(pair, &report);
  result.eligible_a = static_cast<int>(eligible.a.rocks.size());
  result.eligible_b = static_cast<int>(eligible.b.rocks.size());
  const RocksOfBInA b_in_a(pair, eligible.b);
  const AmbiguityTest ambiguous_a(a.rocks, options);
  const AmbiguityTest ambiguous_b(b.rocks, options);
  FateLog fates(&result.outcomes);
  const SignificantRocks significant =
      SelectSignificantRocks(pair, eligible.a, ambiguous_a, &fates);
  result.significant = static_cast<int>(significant.rocks.size());

  // III matching: pattern and model matching, the global pattern, their combination.
  const CandidateSet candidates =
      GenerateCandidates(pair, eligible, b_in_a, significant.rocks, &fates);
  result.model_matches = candidates.model_matches;
  const GlobalPattern pattern = FitGlobalPattern(pair, candidates.vectors);
  result.global_translation = pattern.translation;
  report.Add(RockCount("III matching", "local terrain mismatch (plane normals)",
                       candidates.terrain_rejects, fd.max_normal_angle_deg, "deg"));
  result.global_turn_deg = pattern.motion.turn_rad * kRadToDeg;
  const CombinedMatches combined = CombineMethods(
      pair, eligible.b, b_in_a, pattern, candidates.per_rock, ambiguous_a, ambiguous_b, &fates);
  result.pattern_matches = combined.pattern_matches;
  UniqueMatches unique = KeepLowestCostPerRockOfB(combined.matches, b.rocks.size(), &fates);
  result.matches = std::move(unique.matches);
  report.Add(
      RockCount("III matching", "multiple matches of one rock", unique.multiples, 1, "rocks"));
  report.Add(RockCount("III matching", "ambiguous rock (neighbour within tolerance + k sigma)",
                       significant.ambiguous + combined.ambiguous, options.pattern_tolerance_m,
                       "m"));

  // IV: the outlier test in the site-to-site fit, then the pair-level rules.
  const int outliers = DropResidualOutliers(pair, &result.matches, &fates);
  for (const RockMatch& m : result.matches) fates.Set(m.rock_a, m.rock_b, "matched");
  report.Add(RockCount("IV adjustment", "tie point residual outlier (conformal fit)", outliers,
                       options.max_residual_chi2, "chi2"));
  AddPairLevelChecks(pair, &result);
  if (report.outcome != PairOutcome::kMatched) return result;
  for (const RockMatch& m : result.matches) result.tie_points.push_back(MakeTiePoint(pair, m));
  return result;
}

}  // namespace areomap
