// Cross-site rock matching (ch. 3.2, Fig. 3.3) with fault detection (ch. 4.2, Table 4.5):
// rocks extracted at two sites -> tie points for the bundle adjustment.
//
// Frames: each site's rocks are in its own site frame (x north, y east, z down [m]);
// `a_from_b_prior` is the telemetry (or visual odometry) pose of site b in site a, used only to
// bring b's rocks near a's for the search; its error is what the matching absorbs (the search
// radius must exceed it). Tie points carry each site's own peak position and its stereo covariance
// plus `peak_definition_sigma_m` horizontally.
//
// Steps (ch. 3.2; docs/rocks.md, "Matching", gives each rule's reason and option):
//  1. Per-rock rules (Table 4.5, CheckRockRules): rocks too far, too low, with too few surface
//     points or an implausible model, with a low distance ratio or an imprecise peak are set aside.
//  2. Significant rocks of site a: the `significant_per_cell` highest unambiguous ones per grid
//     cell in the overlap (within max_peak_range_m of both cameras).
//  3. Pattern matching: each candidate of b within the search radius votes with V = P_k - Q_m
//     (eq. 3.29): the rocks of a that b's rocks, shifted by V, bring within epsilon (eqs. 3.30,
//     3.31; epsilon widened to twice the peaks' combined sigma along each principal direction of
//     their horizontal covariance: a far peak smears along its line of sight, not across it). The
//     two best candidates per significant rock are kept (Fig. 3.3).
//  4. Model matching among those two: the smaller PairCost, the relative difference of the two
//     measured peak-to-plane heights or, with `compare_models`, 1/2 f_h + 1/3 f_r + 1/6 f_S
//     (eq. 3.28; relative differences of the best models' height, mean radius and exact surface
//     area, where both rest on `min_shape_points` points); then the local terrain check (angle
//     between the background-plane normals).
//  5. Global consistency: the candidate whose V is nearer, by the chi-square of the two peaks'
//     covariances, the V the global pattern expects there (`consensus_translation`,
//     `consensus_turn`) wins; a winner beyond `max_vector_deviation_m` or `max_vector_chi2` is
//     dropped. A pair is matched where both methods agree, where the pattern vouches for it
//     (`pattern_vouch_*`) or settles the disagreement (`pattern_settles_disagreement`); beyond
//     the dissertation, low pairs seen from afar (`low_pair_max_height_m`) and rocks ambiguous at
//     either site (`ambiguity_*`) are dropped. Of several rocks of a taking one rock of b, the
//     lowest cost is kept.
//  6. Data snooping in the 2D conformal fit of the matches (eq. 4.4), each tie point tested
//     against the fit of the others, drops outliers while more than min_tie_points remain.
//     Pair-level rules (traverse, peaks, tie-point count, distance ratio, RE) decide the outcome.
//
// Failures: invalid options throw areomap::Error; everything about the data (no overlap, no
// rocks, too few tie points) is a verdict in the report, never an exception.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "areomap/landmarks/fault_detection.h"
#include "areomap/landmarks/localization_error.h"
#include "areomap/landmarks/rock_extraction.h"
#include "areomap/map/landmark_links.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

struct SiteRocks {
  int site = -1;
  Eigen::Vector3d camera_center = Eigen::Vector3d::Zero();  // Site frame [m].
  std::vector<ExtractedRock> rocks;
};

// The prior pose of site b in site a with its uncertainty (1 sigma): telemetry (dead reckoning),
// or both sites' poses corrected by orbital registration (much tighter). It bounds the search:
// a rock of b is a candidate for a rock of a within pattern_tolerance_m plus three sigmas of the
// prior's displacement at that rock (position sigma and heading sigma times the rock's distance
// from site b), never beyond RockMatchingOptions::search_radius_m.
struct RockMatchingPrior {
  Rigid3d a_from_b;
  double position_sigma_m = 0.0;   // Horizontal, per axis [m], >= 0; infinity: unknown.
  double heading_sigma_deg = 0.0;  // Relative heading [deg], >= 0.
  std::string source = "telemetry";
  void Check() const;  // Throws areomap::Error naming the field.
};

struct RockMatchingOptions {
  double significant_cell_m = 3.0;  // Grid cell for significant rocks [m].
  // Highest rocks kept per cell (ch. 3.2 keeps one, which throws away good rocks beside the
  // highest; docs/rocks.md, "Three significant rocks per cell").
  int significant_per_cell = 3;
  double search_radius_m = 2.5;         // Largest search radius around a rock of a (prior) [m].
  double pattern_tolerance_m = 0.6;     // epsilon of eq. 3.31 [m].
  double max_vector_deviation_m = 1.0;  // Winner's V from the global V [m], and ...
  // ... its chi-square against the two peaks' covariances plus the prior's heading error acting
  // on the rock's distance from site a (chi-square 3 dof, 99 %: 11.34). The heading sigma is the
  // one of a prior given as a bare pose (the first MatchSitePair overload) [deg].
  double prior_heading_sigma_deg = 2.0;
  double max_vector_chi2 = 11.34;
  // The highest point of a rock seen from two sides is not the same surface point: this sigma
  // (horizontal, each site) is added to the peaks' stereo covariance in the tie points and RE [m].
  double peak_definition_sigma_m = 0.08;
  // Tie points whose discrepancy from the site-to-site conformal fit of the other tie points
  // exceeds this chi-square (LeaveOneOutChi2; 2 dof, 99.9 %: 13.8) are dropped one by one, the
  // worst first, while more than min_tie_points remain.
  double max_residual_chi2 = 13.8;
  // Variance factor (a-posteriori sigma_0^2) applied to the tie points' covariances (the peaks'
  // eq. 4.3 covariance plus the peak definition) in the conformal fit, its outlier test, RE and
  // the output tie points. 1 keeps the a-priori covariances; a run's second pass over its legs
  // sets it to the factor its first pass's conformal fits imply (PoolVarianceFactor's 95 % bound,
  // MissionRunOptions::rock_variance_pass). Check() throws unless finite and > 0.
  double tie_variance_factor = 1.0;
  double cost_height_weight = 0.5;  // c1 of eq. 3.28.
  double cost_radius_weight = 1.0 / 3.0;
  double cost_area_weight = 1.0 / 6.0;
  double max_model_cost = 0.6;  // Model matching accepts costs up to this.
  // Eq. 3.28 compares two models only when both rest on at least this many surface points (half
  // of RockExtractionOptions::max_model_points, the most a fit uses): a model fitted to fewer is
  // not determined (docs/rocks.md, "Models from few points"). Such a pair is compared by its
  // measured peak-to-plane heights instead, as the ambiguity test compares a rock with its
  // neighbours: a relative difference up to ambiguity_similar_height_difference is a cost up to
  // max_model_cost (PairCost). 0 compares every pair's models (ch. 3.2). Applies only with
  // compare_models.
  int min_shape_points = 40;
  // False compares every pair by its measured peak-to-plane heights (PairCost); true uses eq. 3.28
  // of the fitted models for pairs whose models both rest on min_shape_points surface points or
  // more. A rock seen from one side 8-17 m away does not determine its model well enough to tell
  // its partner from a look-alike (docs/rocks.md, "Measured heights, not models").
  bool compare_models = false;
  // When model matching prefers the other pattern candidate ("methods disagree"), but that
  // candidate's V fails the global pattern test (max_vector_deviation_m, max_vector_chi2), the
  // pattern's winner is matched if its own cost is acceptable: as if it were the only candidate,
  // which would be matched. False: every disagreement drops the rock (ch. 3.2).
  bool pattern_settles_disagreement = true;
  // The global pattern's translation (the "median V" of the deviation test): true, the median of
  // the largest group of rocks whose candidate vectors agree within max_vector_deviation_m (the
  // median of all where no two agree); false, the median of all candidate vectors (ch. 3.2), which
  // the wrong candidates pull towards the prior when few rocks and a prior off by metres meet.
  bool consensus_translation = true;
  // The global pattern as a motion, not a translation alone: a small turn about z fitted with the
  // translation to the V of the rocks that agree on the global V (each rock's candidate nearest
  // it, within max_vector_deviation_m; least squares, then again on those within
  // consensus_turn_trim_m of the first fit), so that a candidate's deviation is measured from the
  // V the pattern expects where it lies: the prior's heading error turns b's rocks about b's
  // camera (3.5 cm per metre at 2 degrees). No turn where fewer than three rocks agree, where they
  // spread less than 1 m (rms) about their centre, or where the turn exceeds three sigmas of the
  // prior's heading (docs/rocks.md, "The pattern's turn"). False: the translation alone.
  bool consensus_turn = true;
  double consensus_turn_trim_m = 0.3;  // [m], > 0.
  double ambiguity_sigmas = 1.0;       // Neighbour within epsilon + this many sigmas: ambiguous.
  // Neighbours that count for the ambiguity test: rocks at least this high at their site [m]
  // (lower values guard against a neighbour measured just under the height rule,
  // FaultDetectionOptions::min_peak_to_plane_m, here and over it at the other site, at a cost in
  // matches: docs/rocks.md).
  double ambiguity_min_height_m = 0.15;
  // ... and lower neighbours from this height up whose height differs from the tested rock's by
  // at most this relative difference (|h1 - h2| / mean): a rock measured under the height rule at
  // one site and over it at the other is ambiguous with a neighbour of its own size, which the
  // model matching cannot tell apart either [m], [-]. Setting the first to ambiguity_min_height_m
  // turns it off (docs/rocks.md, "Neighbours of the rock's own height").
  double ambiguity_similar_min_height_m = 0.10;
  double ambiguity_similar_height_difference = 0.3;
  // Rocks whose peak's largest horizontal sigma exceeds this are not used as tie points (eq. 4.3
  // range error grows as r^2: 0.6 m at ~17 m for the Navcam with sigma_p = 0.5 px) [m].
  double max_peak_sigma_m = 0.6;
  // A pair in which both rocks are lower than `low_pair_max_height_m` is matched only while both
  // peaks' largest horizontal sigma is at most `low_rock_max_peak_sigma_m` [m] (0.3 m is reached
  // ~12 m from a Navcam). Low rocks are the commonest (the size-frequency law), and many of a far
  // peak's look-alike neighbours are measured too low to be extracted at all, so the ambiguity
  // test cannot see them (docs/rocks.md, "The height rule at 12 cm", "Low pairs"). A pair with
  // one rock measured from 16 cm up has a rock that stands out at one site at least (measured
  // heights run 2-6 cm under the true ones). The pattern can vouch for a low pair (below).
  double low_rock_max_peak_sigma_m = 0.3;
  double low_pair_max_height_m = 0.16;
  // The global pattern vouches for a pair whose translation V lies within
  // `pattern_vouch_deviation_m` of the global V (with consensus_turn, of the V the pattern
  // expects there) while at least `pattern_vouch_votes` rocks of a (the rock itself included)
  // vote for it (eq. 3.31); such a pair is matched even if it is a low pair seen from afar
  // (above) or its pair cost exceeds max_model_cost (no pattern candidate passed it). A wrong
  // pair joins a rock to a neighbour of its partner 0.3-1.5 m away, a few decimetres off the
  // pattern; a lone rock's V is the global V, hence the votes (docs/rocks.md, "Pairs the pattern
  // vouches for"). 0 m: no pair is vouched for.
  double pattern_vouch_deviation_m = 0.2;
  int pattern_vouch_votes = 3;
  // A rock that, put in the place of either rock of a pair the pattern vouches for, would move V
  // beyond pattern_vouch_deviation_m plus ambiguity_sigmas sigmas of that new pair's peaks
  // (horizontal covariance, along each principal direction) from the global V (with
  // consensus_turn, from the V the pattern expects where that rock lies) is no alternative
  // to the pair: a neighbour so placed does not make it ambiguous, nor does model matching's
  // preference for such a candidate make the methods disagree. The ambiguity test's gate allows
  // for the prior's heading error (2 degrees: 0.7 m at 20 m), which the global V has already
  // measured for the rocks that vote for it (docs/rocks.md, "Alternatives the pattern rules
  // out"). False: such a rock counts as an alternative like any other.
  bool pattern_vouch_rules_out_alternatives = true;
  FaultDetectionOptions fault_detection;
  void Check() const;  // Throws areomap::Error naming the field.
};

struct RockMatch {
  int rock_a = -1;                // Index into SiteRocks::rocks of site a.
  int rock_b = -1;                // Index into SiteRocks::rocks of site b.
  double model_cost = 0.0;        // PairCost: the measured heights, or eq. 3.28.
  int pattern_count = 0;          // Eq. 3.31 for the winning translation.
  double normal_angle_deg = 0.0;  // Between the background-plane normals.
  double distance_ratio = 0.0;    // Fig. 4.19.
};

// What became of one eligible rock of site a in the overlap (diagnostics): `fate` is "matched" or
// the step that dropped it: "ambiguous at a", "not highest in cell", "no candidate",
// "inconsistent vector", "model cost", "terrain mismatch", "methods disagree",
// "low rock seen from afar", "ambiguous at b", "multiple match", "residual outlier".
struct RockMatchOutcome {
  int rock_a = -1;  // Index into SiteRocks::rocks of site a.
  int rock_b = -1;  // The winning candidate of site b, when the rock got that far; else -1.
  std::string fate;
};

struct SitePairMatch {
  std::vector<RockMatch> matches;    // Accepted rock pairs (before the pair-level verdict).
  std::vector<TiePoint> tie_points;  // Only when the pair's outcome is "matched".
  PairFaultReport report;
  std::optional<SitePairError> error;  // RE (eq. 4.9) and geometry of the matches.
  // The global pattern's V (in a) [m]: RockMatchingOptions::consensus_translation.
  Eigen::Vector3d global_translation = Eigen::Vector3d::Zero();
  // Its turn about z (RockMatchingOptions::consensus_turn; 0 where none was fitted) [deg]: the
  // prior's heading error as the rocks measure it.
  double global_turn_deg = 0.0;
  int eligible_a = 0, eligible_b = 0;  // Rocks passing the per-rock rules.
  int significant = 0;
  int model_matches = 0, pattern_matches = 0;
  std::vector<RockMatchOutcome> outcomes;  // One per eligible rock of a in the overlap.
};

// With a bare prior pose: the search radius is options.search_radius_m everywhere and the heading
// sigma options.prior_heading_sigma_deg.
SitePairMatch MatchSitePair(const SiteRocks& a, const SiteRocks& b, const Rigid3d& a_from_b_prior,
                            const RockMatchingOptions& options,
                            const std::optional<StereoQuality>& stereo = std::nullopt);
// With a prior and its sigmas: the search radius follows the prior's uncertainty at each rock.
SitePairMatch MatchSitePair(const SiteRocks& a, const SiteRocks& b, const RockMatchingPrior& prior,
                            const RockMatchingOptions& options,
                            const std::optional<StereoQuality>& stereo = std::nullopt);

// Table 4.5's per-rock rules, in the order they are applied (a rock is counted under the first
// rule it fails). `own` and `other` are the two camera centres in the rock's site frame.
enum class RockRule {
  kEligible,
  kBeyondRange,  // Peak farther than max_peak_range_m from its own camera.
  kTooLow,       // Peak-to-plane distance below min_peak_to_plane_m.
  kFewPoints,    // Fewer than min_surface_points surface points, or no model.
  kImplausible,  // Model height or mean radius above max_model_size_m.
  kLowRatio,     // Distance ratio (Fig. 4.19) below min_rock_distance_ratio.
  kImprecise,    // Largest horizontal peak sigma above max_peak_sigma_m (not Table 4.5).
};
std::string ToString(RockRule rule);
RockRule CheckRockRules(const ExtractedRock& rock, const Eigen::Vector3d& own,
                        const Eigen::Vector3d& other, const RockMatchingOptions& options);

// Rocks that pass the height rule (min_peak_to_plane_m) need a model, so the extraction must model
// every rock at least that high: throws areomap::Error naming
// RockExtractionOptions.model_min_height_m otherwise.
void CheckModelsCoverHeightRule(const RockExtractionOptions& extraction,
                                const RockMatchingOptions& matching);

// Eq. 3.28 between two fitted models (relative differences against their mean).
double ModelMatchCost(const RockModelParameters& p, const RockModelParameters& q,
                      const RockMatchingOptions& options);
// Whether the models of both rocks rest on at least options.min_shape_points surface points (the
// pairs eq. 3.28 compares with options.compare_models).
bool ModelsRestOnShapePoints(const ExtractedRock& p, const ExtractedRock& q,
                             const RockMatchingOptions& options);
// The model matching cost of two rocks: their measured heights' relative difference scaled so
// that ambiguity_similar_height_difference costs max_model_cost; with options.compare_models,
// eq. 3.28 of their best models where both rest on at least options.min_shape_points surface
// points.
double PairCost(const ExtractedRock& p, const ExtractedRock& q, const RockMatchingOptions& options);

}  // namespace areomap
