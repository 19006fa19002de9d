// Internal to rock matching: the stages of MatchSitePair (rock_matching.cc), in the order it runs
// them, and the structs that hand their results on. Frames as in rock_matching.h: each site's
// rocks in its own site frame [m]; "b in a" is a rock of b brought into a's frame by the prior.
// docs/rocks.md ("Matching", "Fault detection") explains the rules.
#pragma once

#include <map>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "areomap/landmarks/fault_detection.h"
#include "areomap/landmarks/rock_matching.h"
#include "rock_matching_geometry.h"
#include "rock_point_grid.h"

namespace areomap::rock_matching_internal {

// The two sites, the prior and the options, with what every stage derives from them.
struct SitePair {
  SitePair(const SiteRocks& site_a, const SiteRocks& site_b, const RockMatchingPrior& pose_prior,
           const RockMatchingOptions& matching);
  const SiteRocks& a;
  const SiteRocks& b;
  const RockMatchingPrior& prior;
  const RockMatchingOptions& options;
  const FaultDetectionOptions& fd;
  Eigen::Vector3d camera_b_in_a;      // Site b's camera in a's frame (by the prior) [m].
  Eigen::Vector3d camera_a_in_b;      // Site a's camera in b's frame [m].
  Eigen::Matrix3d rotation_a_from_b;  // The prior's rotation.
};

// What became of each rock of a (SitePairMatch::outcomes), in the order the rocks were first
// judged; a later fate replaces an earlier one.
class FateLog {
 public:
  explicit FateLog(std::vector<RockMatchOutcome>* outcomes) : outcomes_(outcomes) {}
  void Set(int rock_a, int rock_b, const char* fate);

 private:
  std::vector<RockMatchOutcome>* outcomes_;
  std::map<int, size_t> index_of_;  // Rock of a -> index into *outcomes_.
};

// I and II: the pair-level pre-screening rules (traverse, peaks per site, stereo quality), and the
// rules applied where the data are made, reported so that the report lists every Table 4.5 rule.
void AddPreScreeningChecks(const SitePair& pair, const std::optional<StereoQuality>& stereo,
                           PairFaultReport* report);

// The rocks of one site passing Table 4.5's per-rock rules (CheckRockRules), and how many each
// rule set aside.
struct Eligibility {
  std::vector<int> rocks;  // Indices passing the per-rock rules.
  int beyond_range = 0, too_low = 0, few_points = 0, implausible = 0, low_ratio = 0, imprecise = 0;
};
struct EligibleRocks {
  Eligibility a, b;
};

// III: the per-rock rules at both sites, their counts added to the report.
EligibleRocks SelectEligibleRocks(const SitePair& pair, PairFaultReport* report);

// The eligible rocks of b in a's frame (in Eligibility::rocks order), their peaks' covariances
// turned into a, and a grid of cell epsilon over them for the pattern votes and the search.
struct RocksOfBInA {
  RocksOfBInA(const SitePair& pair, const Eligibility& eligible_b);
  std::vector<Eigen::Vector3d> peaks;        // [m].
  std::vector<Eigen::Matrix3d> covariances;  // [m^2].
  std::vector<PeakSpread> spreads;           // Their horizontal part.
  double max_sigma = 0.0;                    // The largest of the spreads' sigmas [m].
  rock_internal::PointGrid grid;             // Over the peaks' x, y.
};

// Significant rocks of a: the highest unambiguous ones per grid cell, in the overlap (within
// max_peak_range_m of b's camera).
struct SignificantRocks {
  std::vector<int> rocks;  // Indices into a's rocks.
  int ambiguous = 0;       // Rocks of a set aside as ambiguous.
};
SignificantRocks SelectSignificantRocks(const SitePair& pair, const Eligibility& eligible_a,
                                        const AmbiguityTest& ambiguous_a, FateLog* fates);

// A significant rock of a with its two pattern candidates of b (Fig. 3.3) and model matching's
// choice among them. Candidate indices are into Eligibility::rocks of b / RocksOfBInA.
struct RockCandidates {
  int rock_a = -1;
  int model_best = -1;  // -1 where no candidate's cost passed max_model_cost.
  int pattern[2] = {-1, -1};
  int votes[2] = {0, 0};
  double cost[2] = {0.0, 0.0};  // PairCost (eq. 3.28) of each pattern candidate.
};
struct CandidateSet {
  std::vector<RockCandidates> per_rock;  // The significant rocks with a candidate.
  std::vector<CandidateVector> vectors;  // V of every pattern candidate (eq. 3.29).
  int model_matches = 0;                 // Model choices passing the terrain check.
  int terrain_rejects = 0;               // ... and failing it.
};
// Pattern matching (eqs. 3.29-3.31) and model matching (eq. 3.28, the terrain check).
CandidateSet GenerateCandidates(const SitePair& pair, const EligibleRocks& eligible,
                                const RocksOfBInA& b_in_a, const std::vector<int>& significant,
                                FateLog* fates);

// The global pattern the candidates agree on: its translation (SitePairMatch::global_translation)
// and its motion, with a turn where options.consensus_turn fits one.
struct GlobalPattern {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  PatternMotion motion;
};
GlobalPattern FitGlobalPattern(const SitePair& pair, const std::vector<CandidateVector>& vectors);

// Each rock's winner by the global pattern, verified: consistent with the pattern, agreeing
// with model matching (or vouched for, or settled by the pattern), terrain, low pairs seen from
// afar, ambiguity at both sites.
struct CombinedMatches {
  std::vector<RockMatch> matches;  // In per_rock order.
  int pattern_matches = 0;         // Winners consistent with the global pattern.
  int ambiguous = 0;               // Winners dropped as ambiguous at a or b.
};
CombinedMatches CombineMethods(const SitePair& pair, const Eligibility& eligible_b,
                               const RocksOfBInA& b_in_a, const GlobalPattern& pattern,
                               const std::vector<RockCandidates>& per_rock,
                               const AmbiguityTest& ambiguous_a, const AmbiguityTest& ambiguous_b,
                               FateLog* fates);

// Multiple matches: of those taking the same rock of b, the lowest model cost is kept.
struct UniqueMatches {
  std::vector<RockMatch> matches;  // Sorted by rock_a.
  int multiples = 0;               // Matches dropped.
};
UniqueMatches KeepLowestCostPerRockOfB(std::vector<RockMatch> combined, size_t rocks_of_b,
                                       FateLog* fates);

// The match as a tie point: both peaks in their site frames with their covariances (the peak's
// stereo covariance plus the horizontal peak definition, times the variance factor).
TiePoint MakeTiePoint(const SitePair& pair, const RockMatch& m);

// IV: data snooping in the site-to-site conformal fit; returns how many matches it dropped.
int DropResidualOutliers(const SitePair& pair, std::vector<RockMatch>* matches, FateLog* fates);

// IV: the pair-level rules on the matches (distance ratio, tie-point count, RE), which set
// result->error and decide the report's outcome.
void AddPairLevelChecks(const SitePair& pair, SitePairMatch* result);

}  // namespace areomap::rock_matching_internal
