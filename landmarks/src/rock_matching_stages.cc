// The stages of cross-site rock matching (ch. 3.2) and its fault detection (Table 4.5), in the
// order MatchSitePair runs them (rock_matching_stages.h).
#include "rock_matching_stages.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>

#include <Eigen/Cholesky>

#include "areomap/landmarks/leg_consistency.h"
#include "areomap/landmarks/localization_error.h"

namespace areomap::rock_matching_internal {

namespace {

// Table 4.5's per-rock rules. `own` and `other` are the two camera centres in the rocks' frame.
Eligibility SelectEligible(const std::vector<ExtractedRock>& rocks, const Eigen::Vector3d& own,
                           const Eigen::Vector3d& other, const RockMatchingOptions& options) {
  Eligibility e;
  for (size_t i = 0; i < rocks.size(); ++i) {
    switch (CheckRockRules(rocks[i], own, other, options)) {
      case RockRule::kEligible:
        e.rocks.push_back(static_cast<int>(i));
        break;
      case RockRule::kBeyondRange:
        ++e.beyond_range;
        break;
      case RockRule::kTooLow:
        ++e.too_low;
        break;
      case RockRule::kFewPoints:
        ++e.few_points;
        break;
      case RockRule::kImplausible:
        ++e.implausible;
        break;
      case RockRule::kLowRatio:
        ++e.low_ratio;
        break;
      case RockRule::kImprecise:
        ++e.imprecise;
        break;
    }
  }
  return e;
}

std::vector<Eigen::Vector3d> PeaksOfBInA(const SitePair& pair, const Eligibility& eligible_b) {
  std::vector<Eigen::Vector3d> peaks;
  for (int j : eligible_b.rocks) peaks.push_back(pair.prior.a_from_b * pair.b.rocks[j].peak);
  return peaks;
}

std::vector<Eigen::Vector2d> Horizontal(const std::vector<Eigen::Vector3d>& points) {
  std::vector<Eigen::Vector2d> xy;
  for (const Eigen::Vector3d& p : points) xy.push_back(p.head<2>());
  return xy;
}

// Eq. 3.31: how many eligible rocks of a a translation V brings a rock of b to. Epsilon is widened
// to twice the two peaks' combined sigma, along each principal direction of their covariance,
// where the stereo range error (eq. 4.3) exceeds it: far rocks smear along their line of sight,
// not across it.
class PatternVotes {
 public:
  PatternVotes(const SitePair& pair, const Eligibility& eligible_a, const RocksOfBInA& b_in_a)
      : pair_(pair), eligible_a_(eligible_a), b_in_a_(b_in_a) {
    for (int i : eligible_a.rocks) spread_a_.emplace_back(pair.a.rocks[i].peak_covariance);
  }

  int Count(const Eigen::Vector3d& v) const {
    const RockMatchingOptions& options = pair_.options;
    int count = 0;
    for (size_t k = 0; k < eligible_a_.rocks.size(); ++k) {
      const Eigen::Vector3d target = pair_.a.rocks[eligible_a_.rocks[k]].peak - v;
      const double reach =
          std::max(options.pattern_tolerance_m,
                   2.0 * std::hypot(spread_a_[k].largest_sigma, b_in_a_.max_sigma));
      bool hit = false;
      b_in_a_.grid.ForEachNear(target.head<2>(), reach, [&](int j) {
        if (hit || std::abs(b_in_a_.peaks[j].z() - target.z()) > options.pattern_tolerance_m) {
          return;
        }
        hit = EllipticGate::AtLeast(spread_a_[k].covariance + b_in_a_.spreads[j].covariance,
                                    options.pattern_tolerance_m)
                  .Contains((b_in_a_.peaks[j] - target).head<2>());
      });
      count += hit ? 1 : 0;
    }
    return count;
  }

 private:
  const SitePair& pair_;
  const Eligibility& eligible_a_;
  const RocksOfBInA& b_in_a_;
  std::vector<PeakSpread> spread_a_;  // Per eligible rock of a (eligible_a.rocks order).
};

// The two candidates of b within the search radius of rock i of a with the most votes (ties: the
// lower index first).
RockCandidates FindPatternCandidates(const SitePair& pair, const RocksOfBInA& b_in_a,
                                     const PatternVotes& votes, int i) {
  const ExtractedRock& p = pair.a.rocks[i];
  RockCandidates c;
  c.rock_a = i;
  const double radius = SearchRadius(p.peak, pair.camera_b_in_a, pair.prior, pair.options);
  b_in_a.grid.ForEachNear(p.peak.head<2>(), radius, [&](int j) {
    if ((b_in_a.peaks[j] - p.peak).head<2>().norm() > radius) return;
    const int count = votes.Count(p.peak - b_in_a.peaks[j]);
    if (count > c.votes[0] || (count == c.votes[0] && c.pattern[0] >= 0 && j < c.pattern[0])) {
      c.votes[1] = c.votes[0];
      c.pattern[1] = c.pattern[0];
      c.votes[0] = count;
      c.pattern[0] = j;
    } else if (count > c.votes[1] || c.pattern[1] < 0) {
      c.votes[1] = count;
      c.pattern[1] = j;
    }
  });
  return c;
}

// Model matching among the two pattern candidates (Fig. 3.3: local pattern matching limits model
// matching to two candidates): sets each one's cost and model_best to the cheaper; returns its
// cost.
double ChooseByModel(const SitePair& pair, const Eligibility& eligible_b, RockCandidates* c) {
  const ExtractedRock& p = pair.a.rocks[c->rock_a];
  double best_cost = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 2; ++k) {
    if (c->pattern[k] < 0) continue;
    const ExtractedRock& q = pair.b.rocks[eligible_b.rocks[c->pattern[k]]];
    const double cost = PairCost(p, q, pair.options);
    c->cost[k] = cost;
    if (cost < best_cost) {
      best_cost = cost;
      c->model_best = c->pattern[k];
    }
  }
  return best_cost;
}

// The candidate of b that the global pattern prefers for a rock of a: its index, the chi-square
// of its V's deviation, and its pattern slot.
struct Winner {
  int candidate = -1;
  double chi2 = 0.0;
  int slot = 0;
};

// Combines pattern and model matching for each rock of a (CombineMethods). A candidate's V
// deviates from the V the pattern expects there (the global V, turned with consensus_turn) by the
// two peaks' errors plus the prior's heading error acting on the rock's distance from site a
// (kept in full with the turn: a bound, not an estimate); the candidate nearer by that covariance
// wins.
class MethodCombiner {
 public:
  MethodCombiner(const SitePair& pair, const Eligibility& eligible_b, const RocksOfBInA& b_in_a,
                 const PatternMotion& motion, const AmbiguityTest& ambiguous_a,
                 const AmbiguityTest& ambiguous_b, FateLog* fates, CombinedMatches* combined)
      : pair_(pair),
        options_(pair.options),
        eligible_b_(eligible_b),
        b_in_a_(b_in_a),
        motion_(motion),
        ambiguous_a_(ambiguous_a),
        ambiguous_b_(ambiguous_b),
        fates_(fates),
        combined_(combined) {}

  void Judge(const RockCandidates& c) {
    const ExtractedRock& p = pair_.a.rocks[c.rock_a];
    Winner w = ChooseWinner(p, c);
    if (Inconsistent(p, w.candidate, w.chi2)) return Drop(c, w, "inconsistent vector");
    ++combined_->pattern_matches;
    w.slot = w.candidate == c.pattern[0] ? 0 : 1;
    // The global pattern vouches for the winner where it puts b's rock within
    // pattern_vouch_deviation_m of where the other rocks say it should be, with enough votes.
    const bool vouched = options_.pattern_vouch_deviation_m > 0.0 &&
                         c.votes[w.slot] >= options_.pattern_vouch_votes &&
                         DeviationOf(p, w.candidate).norm() <= options_.pattern_vouch_deviation_m;
    // A rock that, put in the place of either rock of a pair the pattern vouches for, moves V
    // beyond pattern_vouch_deviation_m plus ambiguity_sigmas sigmas of the new pair's peaks from
    // the V the pattern expects there is no alternative to that pair
    // (pattern_vouch_rules_out_alternatives).
    const bool rules_out = vouched && options_.pattern_vouch_rules_out_alternatives;
    if (c.model_best < 0 && !vouched) return Drop(c, w, "model cost");
    if (c.model_best >= 0 && w.candidate != c.model_best &&
        !DisagreementSettled(p, c, w.slot, rules_out)) {
      return Drop(c, w, "methods disagree");
    }
    const ExtractedRock& q = pair_.b.rocks[eligible_b_.rocks[w.candidate]];
    const double normal_angle =
        NormalAngleDeg(p.plane_normal, pair_.rotation_a_from_b * q.plane_normal);
    if (normal_angle > pair_.fd.max_normal_angle_deg) return Drop(c, w, "terrain mismatch");
    if (!vouched && std::max(p.height_m, q.height_m) < options_.low_pair_max_height_m &&
        std::max(LargestHorizontalSigma(p), b_in_a_.spreads[w.candidate].largest_sigma) >
            options_.low_rock_max_peak_sigma_m) {
      return Drop(c, w, "low rock seen from afar");
    }
    if (const char* fate = AmbiguityFate(p, c, w.candidate, rules_out)) {
      ++combined_->ambiguous;
      return Drop(c, w, fate);
    }
    RockMatch m;
    m.rock_a = c.rock_a;
    m.rock_b = eligible_b_.rocks[w.candidate];
    m.model_cost = c.cost[w.slot];
    m.pattern_count = c.votes[w.slot];
    m.normal_angle_deg = normal_angle;
    m.distance_ratio = DistanceRatio(p.peak, pair_.a.camera_center, pair_.camera_b_in_a);
    combined_->matches.push_back(m);
  }

 private:
  void Drop(const RockCandidates& c, const Winner& w, const char* fate) {
    fates_->Set(c.rock_a, eligible_b_.rocks[w.candidate], fate);
  }

  // A pair's V from the one the pattern expects there (both rocks in a's frame).
  Eigen::Vector3d PatternDeviation(const Eigen::Vector3d& pa, const Eigen::Vector3d& qa) const {
    return Eigen::Vector3d(pa - qa - motion_.ExpectedV(qa));
  }
  Eigen::Vector3d DeviationOf(const ExtractedRock& p, int candidate) const {
    return PatternDeviation(p.peak, b_in_a_.peaks[candidate]);
  }
  double HeadingLever(const ExtractedRock& p) const {
    return pair_.prior.heading_sigma_deg / kRadToDeg *
           (p.peak - pair_.a.camera_center).head<2>().norm();
  }
  double DeviationChi2(const ExtractedRock& p, int candidate) const {
    const double lever = HeadingLever(p);
    const Eigen::Matrix3d cov = p.peak_covariance + b_in_a_.covariances[candidate] +
                                lever * lever * Eigen::Matrix3d::Identity();
    const Eigen::Vector3d deviation = DeviationOf(p, candidate);
    return deviation.dot(cov.ldlt().solve(deviation));
  }
  bool Inconsistent(const ExtractedRock& p, int candidate, double candidate_chi2) const {
    return DeviationOf(p, candidate).norm() > options_.max_vector_deviation_m ||
           candidate_chi2 > options_.max_vector_chi2;
  }
  bool OffPattern(const Eigen::Vector3d& pa, const Eigen::Vector3d& qa,
                  const Eigen::Matrix2d& covariance) const {
    return !EllipticGate::ToleranceAndSigmas(covariance, options_.pattern_vouch_deviation_m,
                                             options_.ambiguity_sigmas)
                .Contains(PatternDeviation(pa, qa).head<2>());
  }

  // Of the two pattern candidates, the one whose V deviates less from the pattern by chi-square.
  Winner ChooseWinner(const ExtractedRock& p, const RockCandidates& c) const {
    Winner w;
    w.candidate = c.pattern[0];
    w.chi2 = DeviationChi2(p, w.candidate);
    if (c.pattern[1] >= 0) {
      const double chi2_second = DeviationChi2(p, c.pattern[1]);
      if (chi2_second < w.chi2) {
        w.candidate = c.pattern[1];
        w.chi2 = chi2_second;
      }
    }
    return w;
  }

  // The model prefers the other pattern candidate. Where the global pattern excludes that one
  // (the bounds that would have excluded it as the winner), it is no alternative, and the winner
  // is judged as a lone candidate is: by its own model cost and terrain.
  bool DisagreementSettled(const ExtractedRock& p, const RockCandidates& c, int slot,
                           bool rules_out) const {
    return (options_.pattern_settles_disagreement &&
            Inconsistent(p, c.model_best, DeviationChi2(p, c.model_best)) &&
            c.cost[slot] <= options_.max_model_cost) ||
           (rules_out &&
            OffPattern(p.peak, b_in_a_.peaks[c.model_best],
                       HorizontalCovariance(p) + b_in_a_.spreads[c.model_best].covariance));
  }

  // The ambiguity test at b, then at a, with the partner's covariance; the fate of a rock that
  // fails it, else null.
  const char* AmbiguityFate(const ExtractedRock& p, const RockCandidates& c, int winner,
                            bool rules_out) const {
    const SiteRocks& a = pair_.a;
    const SiteRocks& b = pair_.b;
    // The partner's covariance in the tested site's frame, with the prior's heading error: a
    // neighbour that the heading can swap with the rock is no better than one the peaks can.
    const double lever = HeadingLever(p);
    const Eigen::Matrix2d heading = lever * lever * Eigen::Matrix2d::Identity();
    const std::function<bool(int)> alternative_b = [&](int j) {
      return !OffPattern(
          p.peak, pair_.prior.a_from_b * b.rocks[j].peak,
          HorizontalCovariance(p) + HorizontalCovariance(b.rocks[j], pair_.rotation_a_from_b));
    };
    const std::function<bool(int)> alternative_a = [&](int i) {
      return !OffPattern(a.rocks[i].peak, b_in_a_.peaks[winner],
                         HorizontalCovariance(a.rocks[i]) + b_in_a_.spreads[winner].covariance);
    };
    if (ambiguous_b_.Ambiguous(
            eligible_b_.rocks[winner],
            HorizontalCovariance(p, pair_.rotation_a_from_b.transpose()) + heading,
            rules_out ? alternative_b : nullptr)) {
      return "ambiguous at b";
    }
    // The same test at a with the partner's covariance: a far (imprecise) peak of b can as well be
    // a neighbour of p within its uncertainty.
    if (ambiguous_a_.Ambiguous(c.rock_a, b_in_a_.spreads[winner].covariance + heading,
                               rules_out ? alternative_a : nullptr)) {
      return "ambiguous at a";
    }
    return nullptr;
  }

  const SitePair& pair_;
  const RockMatchingOptions& options_;
  const Eligibility& eligible_b_;
  const RocksOfBInA& b_in_a_;
  const PatternMotion& motion_;
  const AmbiguityTest& ambiguous_a_;
  const AmbiguityTest& ambiguous_b_;
  FateLog* fates_;
  CombinedMatches* combined_;
};

// A tie point's covariance at either site: the peak's stereo covariance plus the horizontal peak
// definition, times the variance factor (the fit, its outlier test, RE and the output).
Eigen::Matrix3d TieCovariance(const ExtractedRock& rock, const RockMatchingOptions& options) {
  Eigen::Matrix3d c = rock.peak_covariance;
  c.topLeftCorner<2, 2>() += options.peak_definition_sigma_m * options.peak_definition_sigma_m *
                             Eigen::Matrix2d::Identity();
  return Eigen::Matrix3d(options.tie_variance_factor * c);
}

PlanarTiePoint MakePlanarTie(const SitePair& pair, const RockMatch& m) {
  return PlanarTie(MakeTiePoint(pair, m));
}

}  // namespace

SitePair::SitePair(const SiteRocks& site_a, const SiteRocks& site_b,
                   const RockMatchingPrior& pose_prior, const RockMatchingOptions& matching)
    : a(site_a),
      b(site_b),
      prior(pose_prior),
      options(matching),
      fd(matching.fault_detection),
      camera_b_in_a(pose_prior.a_from_b * site_b.camera_center),
      camera_a_in_b(pose_prior.a_from_b.Inverse() * site_a.camera_center),
      rotation_a_from_b(pose_prior.a_from_b.RotationMatrix()) {}

void FateLog::Set(int rock_a, int rock_b, const char* fate) {
  const auto [it, inserted] = index_of_.try_emplace(rock_a, outcomes_->size());
  if (inserted) outcomes_->push_back({rock_a, -1, ""});
  (*outcomes_)[it->second].rock_b = rock_b;
  (*outcomes_)[it->second].fate = fate;
}

void AddPreScreeningChecks(const SitePair& pair, const std::optional<StereoQuality>& stereo,
                           PairFaultReport* report) {
  const FaultDetectionOptions& fd = pair.fd;
  const double traverse = pair.prior.a_from_b.translation.head<2>().norm();
  report->Add(MaxCheck("I pre-screening", "traverse length", traverse, fd.max_traverse_m, "m"));
  report->Add(MinCheck("II peaks", "peaks at site a", static_cast<double>(pair.a.rocks.size()),
                       fd.min_peaks_per_site, "peaks"));
  report->Add(MinCheck("II peaks", "peaks at site b", static_cast<double>(pair.b.rocks.size()),
                       fd.min_peaks_per_site, "peaks"));
  FaultCheck cc{"II stereo", "matching correlation coefficient", 0.0,  fd.min_correlation,
                "",          FaultVerdict::kNotEvaluated,        false};
  FaultCheck vd{"II stereo", "vertical disparity",        0.0,  fd.max_vertical_disparity_px,
                "px",        FaultVerdict::kNotEvaluated, false};
  if (stereo) {
    cc = MinCheck("II stereo", cc.rule, stereo->min_correlation, fd.min_correlation, "", false);
    vd = MaxCheck("II stereo", vd.rule, stereo->max_vertical_disparity_px,
                  fd.max_vertical_disparity_px, "px", false);
  }
  report->Add(cc);
  report->Add(vd);
  // Applied where the data are made, reported so that the report lists every Table 4.5 rule.
  report->Add({"II stereo", "left-right consistency check (in stereo matching)", 0.0, 0.0, "",
               FaultVerdict::kNotEvaluated, false});
  report->Add({"II stereo", "XYZ intersection computable (in stereo matching)", 0.0, 0.0, "",
               FaultVerdict::kNotEvaluated, false});
  report->Add({"III peaks", "peak window points (applied by ExtractRocks)", 0.0,
               static_cast<double>(fd.min_window_points), "points", FaultVerdict::kNotEvaluated,
               false});
}

EligibleRocks SelectEligibleRocks(const SitePair& pair, PairFaultReport* report) {
  const FaultDetectionOptions& fd = pair.fd;
  EligibleRocks e;
  e.a = SelectEligible(pair.a.rocks, pair.a.camera_center, pair.camera_b_in_a, pair.options);
  e.b = SelectEligible(pair.b.rocks, pair.b.camera_center, pair.camera_a_in_b, pair.options);
  const Eligibility& ea = e.a;
  const Eligibility& eb = e.b;
  report->Add(RockCount("III peaks", "rock peak beyond range of its camera",
                        ea.beyond_range + eb.beyond_range, fd.max_peak_range_m, "m"));
  report->Add(RockCount("III peaks", "rock peak-to-plane distance too small",
                        ea.too_low + eb.too_low, fd.min_peak_to_plane_m, "m"));
  report->Add(RockCount("III peaks", "rock distance ratio too small", ea.low_ratio + eb.low_ratio,
                        fd.min_rock_distance_ratio, ""));
  report->Add(RockCount("III peaks", "rock peak sigma above limit (not Table 4.5)",
                        ea.imprecise + eb.imprecise, pair.options.max_peak_sigma_m, "m"));
  report->Add(RockCount("III modeling", "rock with too few surface points / no model",
                        ea.few_points + eb.few_points, fd.min_surface_points, "points"));
  report->Add(RockCount("III modeling", "rock model implausible (height or radius)",
                        ea.implausible + eb.implausible, fd.max_model_size_m, "m"));
  return e;
}

RocksOfBInA::RocksOfBInA(const SitePair& pair, const Eligibility& eligible_b)
    : peaks(PeaksOfBInA(pair, eligible_b)),
      grid(Horizontal(peaks), pair.options.pattern_tolerance_m) {
  const Eigen::Matrix3d& rotation = pair.rotation_a_from_b;
  for (int j : eligible_b.rocks) {
    covariances.push_back(rotation * pair.b.rocks[j].peak_covariance * rotation.transpose());
    spreads.emplace_back(covariances.back());
    max_sigma = std::max(max_sigma, spreads.back().largest_sigma);
  }
}

// Neighbours that make a rock ambiguous are counted modeled or not (a rock too sparse to model
// can still be the true partner).
SignificantRocks SelectSignificantRocks(const SitePair& pair, const Eligibility& eligible_a,
                                        const AmbiguityTest& ambiguous_a, FateLog* fates) {
  const SiteRocks& a = pair.a;
  const RockMatchingOptions& options = pair.options;
  SignificantRocks significant;
  std::map<std::pair<long, long>, std::vector<int>> cells;
  for (int i : eligible_a.rocks) {
    const ExtractedRock& r = a.rocks[i];
    if ((r.peak - pair.camera_b_in_a).head<2>().norm() > pair.fd.max_peak_range_m) continue;
    if (ambiguous_a.Ambiguous(i)) {
      ++significant.ambiguous;
      fates->Set(i, -1, "ambiguous at a");
      continue;
    }
    const auto key =
        std::make_pair(std::lround(std::floor(r.peak.x() / options.significant_cell_m)),
                       std::lround(std::floor(r.peak.y() / options.significant_cell_m)));
    cells[key].push_back(i);
  }
  for (auto& [key, members] : cells) {
    std::sort(members.begin(), members.end(),
              [&](int x, int y) { return a.rocks[x].height_m > a.rocks[y].height_m; });
    const int keep = std::min(options.significant_per_cell, static_cast<int>(members.size()));
    for (int k = 0; k < static_cast<int>(members.size()); ++k) {
      if (k < keep) {
        significant.rocks.push_back(members[k]);
      } else {
        fates->Set(members[k], -1, "not highest in cell");
      }
    }
  }
  return significant;
}

CandidateSet GenerateCandidates(const SitePair& pair, const EligibleRocks& eligible,
                                const RocksOfBInA& b_in_a, const std::vector<int>& significant,
                                FateLog* fates) {
  const PatternVotes votes(pair, eligible.a, b_in_a);
  CandidateSet set;
  for (int i : significant) {
    const ExtractedRock& p = pair.a.rocks[i];
    RockCandidates c = FindPatternCandidates(pair, b_in_a, votes, i);
    if (c.pattern[0] < 0) {  // No candidate near this rock.
      fates->Set(i, -1, "no candidate");
      continue;
    }
    const double best_cost = ChooseByModel(pair, eligible.b, &c);
    if (best_cost <= pair.options.max_model_cost) {
      const ExtractedRock& q = pair.b.rocks[eligible.b.rocks[c.model_best]];
      const double angle = NormalAngleDeg(p.plane_normal, pair.rotation_a_from_b * q.plane_normal);
      const bool terrain_ok = angle <= pair.fd.max_normal_angle_deg;
      set.terrain_rejects += terrain_ok ? 0 : 1;
      set.model_matches += terrain_ok ? 1 : 0;
    } else {
      c.model_best = -1;
    }
    for (int k = 0; k < 2; ++k) {
      if (c.pattern[k] < 0) continue;
      set.vectors.push_back({static_cast<int>(set.per_rock.size()),
                             p.peak - b_in_a.peaks[c.pattern[k]], b_in_a.peaks[c.pattern[k]]});
    }
    set.per_rock.push_back(c);
  }
  return set;
}

GlobalPattern FitGlobalPattern(const SitePair& pair, const std::vector<CandidateVector>& vectors) {
  const RockMatchingOptions& options = pair.options;
  GlobalPattern pattern;
  pattern.translation =
      GlobalTranslation(vectors, options.consensus_translation, options.max_vector_deviation_m);
  pattern.motion =
      options.consensus_turn
          ? FitPatternMotion(vectors, pattern.translation, options.max_vector_deviation_m,
                             options.consensus_turn_trim_m,
                             3.0 * pair.prior.heading_sigma_deg / kRadToDeg)
          : PatternMotion{pattern.translation};
  return pattern;
}

CombinedMatches CombineMethods(const SitePair& pair, const Eligibility& eligible_b,
                               const RocksOfBInA& b_in_a, const GlobalPattern& pattern,
                               const std::vector<RockCandidates>& per_rock,
                               const AmbiguityTest& ambiguous_a, const AmbiguityTest& ambiguous_b,
                               FateLog* fates) {
  CombinedMatches combined;
  MethodCombiner combiner(pair, eligible_b, b_in_a, pattern.motion, ambiguous_a, ambiguous_b, fates,
                          &combined);
  for (const RockCandidates& c : per_rock) combiner.Judge(c);
  return combined;
}

UniqueMatches KeepLowestCostPerRockOfB(std::vector<RockMatch> combined, size_t rocks_of_b,
                                       FateLog* fates) {
  std::sort(combined.begin(), combined.end(), [](const RockMatch& x, const RockMatch& y) {
    return x.model_cost != y.model_cost ? x.model_cost < y.model_cost : x.rock_a < y.rock_a;
  });
  UniqueMatches unique;
  std::vector<char> taken(rocks_of_b, 0);
  for (const RockMatch& m : combined) {
    if (taken[m.rock_b]) {
      ++unique.multiples;
      fates->Set(m.rock_a, m.rock_b, "multiple match");
      continue;
    }
    taken[m.rock_b] = 1;
    unique.matches.push_back(m);
  }
  std::sort(unique.matches.begin(), unique.matches.end(),
            [](const RockMatch& x, const RockMatch& y) { return x.rock_a < y.rock_a; });
  return unique;
}

TiePoint MakeTiePoint(const SitePair& pair, const RockMatch& m) {
  const ExtractedRock& p = pair.a.rocks[m.rock_a];
  const ExtractedRock& q = pair.b.rocks[m.rock_b];
  TiePoint t;
  char id[64];
  std::snprintf(id, sizeof(id), "s%03d-s%03d-r%d", pair.a.site, pair.b.site, p.id);
  t.id = id;
  t.site_a = pair.a.site;
  t.site_b = pair.b.site;
  t.position_in_a = p.peak;
  t.covariance_in_a = TieCovariance(p, pair.options);
  t.position_in_b = q.peak;
  t.covariance_in_b = TieCovariance(q, pair.options);
  t.source = "rock";
  return t;
}

// Outlier test in the site-to-site adjustment (data snooping): with redundancy left, the tie
// point that disagrees most with the conformal fit (eq. 4.4) of the others, if its chi-square
// exceeds `max_residual_chi2` (LeaveOneOutChi2), is dropped and the test repeated.
int DropResidualOutliers(const SitePair& pair, std::vector<RockMatch>* matches, FateLog* fates) {
  int outliers = 0;
  while (static_cast<int>(matches->size()) > pair.fd.min_tie_points) {
    std::vector<PlanarTiePoint> ties;
    for (const RockMatch& m : *matches) ties.push_back(MakePlanarTie(pair, m));
    const std::vector<double> chi2 = LeaveOneOutChi2(ties);
    size_t worst = 0;
    double worst_chi2 = 0.0;
    for (size_t k = 0; k < chi2.size(); ++k) {
      if (chi2[k] > worst_chi2) {  // NaN (the others not fittable) never is
        worst_chi2 = chi2[k];
        worst = k;
      }
    }
    if (worst_chi2 <= pair.options.max_residual_chi2) break;
    fates->Set((*matches)[worst].rock_a, (*matches)[worst].rock_b, "residual outlier");
    matches->erase(matches->begin() + static_cast<long>(worst));
    ++outliers;
  }
  return outliers;
}

void AddPairLevelChecks(const SitePair& pair, SitePairMatch* result) {
  const FaultDetectionOptions& fd = pair.fd;
  PairFaultReport& report = result->report;
  double ratio_sum = 0.0;
  std::vector<PlanarTiePoint> planar;
  for (const RockMatch& m : result->matches) {
    ratio_sum += m.distance_ratio;
    planar.push_back(MakePlanarTie(pair, m));
  }
  const double mean_ratio =
      result->matches.empty() ? 0.0 : ratio_sum / static_cast<double>(result->matches.size());
  report.Add(MinCheck("III peaks", "averaged distance ratio of the matched rocks", mean_ratio,
                      fd.min_pair_distance_ratio, ""));
  report.Add(MinCheck("IV adjustment", "number of tie points",
                      static_cast<double>(result->matches.size()), fd.min_tie_points, "points"));
  if (static_cast<int>(planar.size()) >= 2) {
    result->error = EvaluateSitePair(planar, pair.prior.a_from_b.translation.head<2>());
  }
  if (result->error) {
    report.Add(MaxCheck("IV adjustment", "relative error RE (eq. 4.9)",
                        result->error->relative_error_percent, fd.max_relative_error_percent, "%"));
  } else if (planar.size() >= 2) {
    // Tie points the conformal fit cannot adjust (degenerate, or not converging): RE unknown,
    // and a leg is never accepted without it.
    report.Add({"IV adjustment", "relative error RE (eq. 4.9)", std::nan(""),
                fd.max_relative_error_percent, "%", FaultVerdict::kFail, true});
  } else {
    report.Add({"IV adjustment", "relative error RE (eq. 4.9)", std::nan(""),
                fd.max_relative_error_percent, "%", FaultVerdict::kNotEvaluated, false});
  }
}

}  // namespace areomap::rock_matching_internal
