// Cross-site rock matching (ch. 3.2) with the fault detection rules of Table 4.5.
#include "areomap/landmarks/rock_matching.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "areomap/landmarks/leg_consistency.h"
#include "areomap/map/error.h"
#include "rock_point_grid.h"

namespace areomap {

namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

double RelativeDifference(double x, double y) {
  const double mean = 0.5 * (std::abs(x) + std::abs(y));
  return mean > 0.0 ? std::abs(x - y) / mean : 0.0;
}

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  const double upper = values[mid];
  if (values.size() % 2 == 1) return upper;
  return 0.5 * (upper + *std::max_element(values.begin(), values.begin() + mid));
}

// A pattern candidate's translation V = P - Q (eq. 3.29) and the rock of site a it was found for.
struct CandidateVector {
  int rock = -1;  // Index of the rock of a among those with candidates.
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d q = Eigen::Vector3d::Zero();  // The candidate of b, in a's frame [m].
};

Eigen::Vector3d ComponentMedian(const std::vector<CandidateVector>& vectors) {
  std::vector<double> x, y, z;
  for (const CandidateVector& c : vectors) {
    x.push_back(c.v.x());
    y.push_back(c.v.y());
    z.push_back(c.v.z());
  }
  return {Median(x), Median(y), Median(z)};
}

// Of each rock, its vector nearest `centre` within agreement_m horizontally: rock -> (distance,
// index into vectors).
std::map<int, std::pair<double, size_t>> NearestPerRock(const std::vector<CandidateVector>& vectors,
                                                        const Eigen::Vector3d& centre,
                                                        double agreement_m) {
  std::map<int, std::pair<double, size_t>> nearest;
  for (size_t j = 0; j < vectors.size(); ++j) {
    const double d = (vectors[j].v - centre).head<2>().norm();
    if (d > agreement_m) continue;
    const auto [it, inserted] = nearest.try_emplace(vectors[j].rock, d, j);
    if (!inserted && d < it->second.first) it->second = {d, j};
  }
  return nearest;
}

// The global pattern's translation from the candidate vectors of all rocks. Ch. 3.2 takes their
// median. With `consensus`, it is the median of the largest group of rocks that agree: the
// candidate vector that the most rocks have a vector within `agreement_m` of (horizontally; ties:
// the smaller summed distance of those vectors, then the first), and of each such rock its vector
// nearest it. Where no two rocks agree, the median of all. (Few rocks with a prior off by 2 m: the
// wrong candidates scatter about the prior and pull the median halfway, so the true pattern's
// vectors all fail the deviation test; docs/rocks.md, "The pattern's consensus".)
Eigen::Vector3d GlobalTranslation(const std::vector<CandidateVector>& vectors, bool consensus,
                                  double agreement_m) {
  if (!consensus) return ComponentMedian(vectors);
  std::map<int, std::pair<double, size_t>> best;
  double best_spread = std::numeric_limits<double>::infinity();
  for (const CandidateVector& seed : vectors) {
    auto nearest = NearestPerRock(vectors, seed.v, agreement_m);
    double spread = 0.0;
    for (const auto& [rock, entry] : nearest) spread += entry.first;
    if (nearest.size() > best.size() || (nearest.size() == best.size() && spread < best_spread)) {
      best = std::move(nearest);
      best_spread = spread;
    }
  }
  if (best.size() < 2) return ComponentMedian(vectors);
  std::vector<CandidateVector> group;
  for (const auto& [rock, entry] : best) group.push_back(vectors[entry.second]);
  return ComponentMedian(group);
}

// The global pattern as a motion: the translation V at `pivot` and a small turn about the z axis,
// so that the V expected of a candidate at q (in a's frame) is V + turn x (q - pivot).
struct PatternMotion {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // [m].
  Eigen::Vector2d pivot = Eigen::Vector2d::Zero();        // [m], in a's frame.
  double turn_rad = 0.0;
  Eigen::Vector3d ExpectedV(const Eigen::Vector3d& q) const {
    const Eigen::Vector2d d = q.head<2>() - pivot;
    return translation + turn_rad * Eigen::Vector3d(-d.y(), d.x(), 0.0);
  }
};

// The turn of the global pattern: of each rock, its candidate vector nearest `translation`
// (within agreement_m horizontally); V_i = t + turn x (q_i - pivot) fitted by least squares to
// them, then again to those within trim_m of the first fit. No turn (the translation alone)
// where fewer than three rocks agree, where their candidates spread less than 1 m (rms) about
// their centre (the turn is not determined), or where the fitted turn exceeds max_turn_rad.
PatternMotion FitPatternMotion(const std::vector<CandidateVector>& vectors,
                               const Eigen::Vector3d& translation, double agreement_m,
                               double trim_m, double max_turn_rad) {
  PatternMotion motion;
  motion.translation = translation;
  std::vector<const CandidateVector*> group;
  for (const auto& [rock, entry] : NearestPerRock(vectors, translation, agreement_m)) {
    group.push_back(&vectors[entry.second]);
  }
  for (int pass = 0; pass < 2; ++pass) {
    if (group.size() < 3) return motion;
    Eigen::Vector2d pivot = Eigen::Vector2d::Zero();
    for (const CandidateVector* c : group) pivot += c->q.head<2>();
    pivot /= static_cast<double>(group.size());
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    double spread = 0.0;
    for (const CandidateVector* c : group) {
      const Eigen::Vector2d d = c->q.head<2>() - pivot;
      spread += d.squaredNorm();
      const Eigen::Vector3d row_x(1.0, 0.0, -d.y()), row_y(0.0, 1.0, d.x());
      normal += row_x * row_x.transpose() + row_y * row_y.transpose();
      rhs += row_x * c->v.x() + row_y * c->v.y();
    }
    if (spread / static_cast<double>(group.size()) < 1.0) return motion;
    const Eigen::Vector3d x = normal.ldlt().solve(rhs);
    if (!x.allFinite() || std::abs(x.z()) > max_turn_rad) return motion;
    PatternMotion fitted;
    fitted.translation = Eigen::Vector3d(x.x(), x.y(), translation.z());
    fitted.pivot = pivot;
    fitted.turn_rad = x.z();
    if (pass == 1) return fitted;
    std::vector<const CandidateVector*> kept;
    for (const CandidateVector* c : group) {
      if ((c->v - fitted.ExpectedV(c->q)).head<2>().norm() <= trim_m) kept.push_back(c);
    }
    group = std::move(kept);
  }
  return motion;
}

// The horizontal covariance of a rock's peak, turned by `rotation` (into another site's frame).
Eigen::Matrix2d HorizontalCovariance(
    const ExtractedRock& r, const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity()) {
  return (rotation * r.peak_covariance * rotation.transpose()).topLeftCorner<2, 2>();
}

// The horizontal covariance of a rock's peak and its largest sigma, computed once per pair.
struct PeakSpread {
  explicit PeakSpread(const Eigen::Matrix3d& covariance_in_frame)
      : covariance(covariance_in_frame.topLeftCorner<2, 2>()) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen;
    eigen.computeDirect(covariance, Eigen::EigenvaluesOnly);
    largest_sigma = std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
  }
  Eigen::Matrix2d covariance;  // [m^2].
  double largest_sigma = 0.0;  // [m].
};

double LargestHorizontalSigma(const ExtractedRock& r) {
  return PeakSpread(r.peak_covariance).largest_sigma;
}

// A horizontal gate about a peak, shaped by the covariance of the two peaks' difference: an
// ellipse whose semi-axis along each principal direction of the covariance is a function of the
// sigma there. A far stereo peak is uncertain along its line of sight only (eq. 4.3: range error
// grows as r^2, the azimuth error as r), so a gate drawn with its largest sigma in every
// direction takes in neighbours that its precise bearing already tells apart.
class EllipticGate {
 public:
  // Semi-axes `tolerance` + `sigmas` x sigma (the ambiguity test).
  static EllipticGate ToleranceAndSigmas(const Eigen::Matrix2d& covariance, double tolerance,
                                         double sigmas) {
    return EllipticGate(covariance, [&](double sigma) { return tolerance + sigmas * sigma; });
  }
  // Semi-axes max(`tolerance`, 2 sigma) (eq. 3.31's epsilon, widened where the peaks smear).
  static EllipticGate AtLeast(const Eigen::Matrix2d& covariance, double tolerance) {
    return EllipticGate(covariance, [&](double sigma) { return std::max(tolerance, 2.0 * sigma); });
  }
  bool Contains(const Eigen::Vector2d& offset) const {
    return (axes_.transpose() * offset).cwiseQuotient(semi_).squaredNorm() <= 1.0;
  }
  double LargestSemiAxis() const { return semi_.maxCoeff(); }

 private:
  template <typename SemiAxis>
  EllipticGate(const Eigen::Matrix2d& covariance, SemiAxis semi_axis) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen;
    eigen.computeDirect(covariance);
    axes_ = eigen.eigenvectors();
    for (int k = 0; k < 2; ++k) {
      semi_[k] = semi_axis(std::sqrt(std::max(0.0, eigen.eigenvalues()[k])));
    }
  }
  Eigen::Matrix2d axes_;  // Principal directions (columns).
  Eigen::Vector2d semi_;  // Semi-axes along them [m], > 0.
};

struct Eligibility {
  std::vector<int> rocks;  // Indices passing the per-rock rules.
  int beyond_range = 0, too_low = 0, few_points = 0, implausible = 0, low_ratio = 0, imprecise = 0;
};

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

// A rock is ambiguous when another rock of its site lies within the pattern tolerance plus
// `sigmas` sigmas of its peak's covariance combined with its partner's (EllipticGate: along each
// principal direction): no translation vote can tell them apart. Neighbours count when at least
// `min_height` high, or at least `similar_min_height` high with a height like the tested rock's
// (a rock measured just under the height rule here may be over it at the other site, and the
// partner's model cannot tell two rocks of one size apart).
class AmbiguityTest {
 public:
  AmbiguityTest(const std::vector<ExtractedRock>& rocks, const RockMatchingOptions& options)
      : rocks_(rocks),
        neighbours_(Neighbours(rocks, options)),
        options_(options),
        grid_(Peaks(rocks, neighbours_), 1.0) {}
  // `partner_covariance`: horizontal covariance of the peak it would be matched with, in this
  // site's frame [m^2]. `alternative`, where given, says whether a neighbour (index into the
  // site's rocks) could take the rock's place; one it rules out does not make the rock ambiguous.
  bool Ambiguous(int i, const Eigen::Matrix2d& partner_covariance = Eigen::Matrix2d::Zero(),
                 const std::function<bool(int)>& alternative = nullptr) const {
    const ExtractedRock& r = rocks_[i];
    const EllipticGate gate =
        EllipticGate::ToleranceAndSigmas(HorizontalCovariance(r) + partner_covariance,
                                         options_.pattern_tolerance_m, options_.ambiguity_sigmas);
    bool ambiguous = false;
    grid_.ForEachNear(r.peak.head<2>(), gate.LargestSemiAxis(), [&](int k) {
      const int j = neighbours_[k];
      ambiguous = ambiguous || (j != i && Counts(rocks_[j], r) &&
                                gate.Contains((rocks_[j].peak - r.peak).head<2>()) &&
                                (!alternative || alternative(j)));
    });
    return ambiguous;
  }

 private:
  bool Counts(const ExtractedRock& neighbour, const ExtractedRock& tested) const {
    return neighbour.height_m >= options_.ambiguity_min_height_m ||
           RelativeDifference(neighbour.height_m, tested.height_m) <=
               options_.ambiguity_similar_height_difference;
  }
  static std::vector<int> Neighbours(const std::vector<ExtractedRock>& rocks,
                                     const RockMatchingOptions& options) {
    const double lowest =
        std::min(options.ambiguity_min_height_m, options.ambiguity_similar_min_height_m);
    std::vector<int> indices;
    for (size_t i = 0; i < rocks.size(); ++i) {
      if (rocks[i].height_m >= lowest) indices.push_back(static_cast<int>(i));
    }
    return indices;
  }
  static std::vector<Eigen::Vector2d> Peaks(const std::vector<ExtractedRock>& rocks,
                                            const std::vector<int>& indices) {
    std::vector<Eigen::Vector2d> xy;
    for (int i : indices) xy.push_back(rocks[i].peak.head<2>());
    return xy;
  }
  const std::vector<ExtractedRock>& rocks_;
  const std::vector<int> neighbours_;
  const RockMatchingOptions& options_;
  rock_internal::PointGrid grid_;
};

// Search radius around a rock of a at `peak`: the pattern tolerance plus three sigmas of the
// prior's displacement there (its position sigma and its heading sigma acting on the distance
// from site b's camera, about which b's rocks are turned), capped at options.search_radius_m.
double SearchRadius(const Eigen::Vector3d& peak, const Eigen::Vector3d& camera_b_in_a,
                    const RockMatchingPrior& prior, const RockMatchingOptions& options) {
  if (std::isinf(prior.position_sigma_m)) return options.search_radius_m;
  const double lever =
      (peak - camera_b_in_a).head<2>().norm() * prior.heading_sigma_deg / kRadToDeg;
  const double sigma = std::hypot(prior.position_sigma_m, lever);
  return std::min(options.search_radius_m, options.pattern_tolerance_m + 3.0 * sigma);
}

double NormalAngleDeg(const Eigen::Vector3d& n1, const Eigen::Vector3d& n2) {
  return std::acos(std::clamp(n1.normalized().dot(n2.normalized()), -1.0, 1.0)) * kRadToDeg;
}

}  // namespace

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
  const Rigid3d& a_from_b_prior = prior.a_from_b;
  const FaultDetectionOptions& fd = options.fault_detection;
  SitePairMatch result;
  PairFaultReport& report = result.report;
  report.site_a = a.site;
  report.site_b = b.site;
  const Rigid3d b_from_a_prior = a_from_b_prior.Inverse();
  const Eigen::Vector3d camera_b_in_a = a_from_b_prior * b.camera_center;
  const Eigen::Vector3d camera_a_in_b = b_from_a_prior * a.camera_center;

  // I and II: pre-screening.
  const double traverse = a_from_b_prior.translation.head<2>().norm();
  report.Add(MaxCheck("I pre-screening", "traverse length", traverse, fd.max_traverse_m, "m"));
  report.Add(MinCheck("II peaks", "peaks at site a", static_cast<double>(a.rocks.size()),
                      fd.min_peaks_per_site, "peaks"));
  report.Add(MinCheck("II peaks", "peaks at site b", static_cast<double>(b.rocks.size()),
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
  report.Add(cc);
  report.Add(vd);
  // Applied where the data are made, reported so that the report lists every Table 4.5 rule.
  report.Add({"II stereo", "left-right consistency check (in stereo matching)", 0.0, 0.0, "",
              FaultVerdict::kNotEvaluated, false});
  report.Add({"II stereo", "XYZ intersection computable (in stereo matching)", 0.0, 0.0, "",
              FaultVerdict::kNotEvaluated, false});
  report.Add({"III peaks", "peak window points (applied by ExtractRocks)", 0.0,
              static_cast<double>(fd.min_window_points), "points", FaultVerdict::kNotEvaluated,
              false});
  if (report.outcome == PairOutcome::kExcludedByPreScreening) return result;

  // III: per-rock rules.
  const Eligibility ea = SelectEligible(a.rocks, a.camera_center, camera_b_in_a, options);
  const Eligibility eb = SelectEligible(b.rocks, b.camera_center, camera_a_in_b, options);
  result.eligible_a = static_cast<int>(ea.rocks.size());
  result.eligible_b = static_cast<int>(eb.rocks.size());
  report.Add(RockCount("III peaks", "rock peak beyond range of its camera",
                       ea.beyond_range + eb.beyond_range, fd.max_peak_range_m, "m"));
  report.Add(RockCount("III peaks", "rock peak-to-plane distance too small",
                       ea.too_low + eb.too_low, fd.min_peak_to_plane_m, "m"));
  report.Add(RockCount("III peaks", "rock distance ratio too small", ea.low_ratio + eb.low_ratio,
                       fd.min_rock_distance_ratio, ""));
  report.Add(RockCount("III peaks", "rock peak sigma above limit (not Table 4.5)",
                       ea.imprecise + eb.imprecise, options.max_peak_sigma_m, "m"));
  report.Add(RockCount("III modeling", "rock with too few surface points / no model",
                       ea.few_points + eb.few_points, fd.min_surface_points, "points"));
  report.Add(RockCount("III modeling", "rock model implausible (height or radius)",
                       ea.implausible + eb.implausible, fd.max_model_size_m, "m"));

  // Rocks of b in a's frame, indexed on a grid of cell epsilon for the pattern votes.
  std::vector<Eigen::Vector3d> q_in_a;
  std::vector<Eigen::Vector2d> q_xy;
  for (int j : eb.rocks) {
    q_in_a.push_back(a_from_b_prior * b.rocks[j].peak);
    q_xy.push_back(q_in_a.back().head<2>());
  }
  const rock_internal::PointGrid q_grid(q_xy, options.pattern_tolerance_m);
  // Eq. 3.31 with epsilon widened to twice the two peaks' combined sigma, along each principal
  // direction of their covariance, where the stereo range error (eq. 4.3) exceeds it: far rocks
  // smear along their line of sight, not across it.
  const Eigen::Matrix3d rotation_a_from_b = a_from_b_prior.RotationMatrix();
  std::vector<Eigen::Matrix3d> covariance_b_in_a;  // b's peaks' covariances turned into a.
  std::vector<PeakSpread> spread_b;                // ... their horizontal part.
  double max_sigma_b = 0.0;
  for (int j : eb.rocks) {
    covariance_b_in_a.push_back(rotation_a_from_b * b.rocks[j].peak_covariance *
                                rotation_a_from_b.transpose());
    spread_b.emplace_back(covariance_b_in_a.back());
    max_sigma_b = std::max(max_sigma_b, spread_b.back().largest_sigma);
  }
  std::vector<PeakSpread> spread_a;  // Per eligible rock of a (ea.rocks order).
  for (int i : ea.rocks) spread_a.emplace_back(a.rocks[i].peak_covariance);
  const auto count_votes = [&](const Eigen::Vector3d& v) {
    int count = 0;
    for (size_t k = 0; k < ea.rocks.size(); ++k) {
      const Eigen::Vector3d target = a.rocks[ea.rocks[k]].peak - v;
      const double reach = std::max(options.pattern_tolerance_m,
                                    2.0 * std::hypot(spread_a[k].largest_sigma, max_sigma_b));
      bool hit = false;
      q_grid.ForEachNear(target.head<2>(), reach, [&](int j) {
        if (hit || std::abs(q_in_a[j].z() - target.z()) > options.pattern_tolerance_m) return;
        hit = EllipticGate::AtLeast(spread_a[k].covariance + spread_b[j].covariance,
                                    options.pattern_tolerance_m)
                  .Contains((q_in_a[j] - target).head<2>());
      });
      count += hit ? 1 : 0;
    }
    return count;
  };

  // Significant rocks of a: the highest unambiguous one per grid cell, in the overlap.
  // Neighbours that make a rock ambiguous are counted modeled or not (a rock too sparse to model
  // can still be the true partner).
  const AmbiguityTest ambiguous_a(a.rocks, options);
  const AmbiguityTest ambiguous_b(b.rocks, options);
  int ambiguous = 0;
  std::map<int, size_t> outcome_of;  // Rock of a -> index into result.outcomes.
  const auto set_fate = [&](int rock_a, int rock_b, const char* fate) {
    const auto [it, inserted] = outcome_of.try_emplace(rock_a, result.outcomes.size());
    if (inserted) result.outcomes.push_back({rock_a, -1, ""});
    result.outcomes[it->second].rock_b = rock_b;
    result.outcomes[it->second].fate = fate;
  };
  std::map<std::pair<long, long>, std::vector<int>> cells;
  for (int i : ea.rocks) {
    const ExtractedRock& r = a.rocks[i];
    if ((r.peak - camera_b_in_a).head<2>().norm() > fd.max_peak_range_m) continue;
    if (ambiguous_a.Ambiguous(i)) {
      ++ambiguous;
      set_fate(i, -1, "ambiguous at a");
      continue;
    }
    const auto key =
        std::make_pair(std::lround(std::floor(r.peak.x() / options.significant_cell_m)),
                       std::lround(std::floor(r.peak.y() / options.significant_cell_m)));
    cells[key].push_back(i);
  }
  std::vector<int> significant;
  for (auto& [key, members] : cells) {
    std::sort(members.begin(), members.end(),
              [&](int x, int y) { return a.rocks[x].height_m > a.rocks[y].height_m; });
    const int keep = std::min(options.significant_per_cell, static_cast<int>(members.size()));
    for (int k = 0; k < static_cast<int>(members.size()); ++k) {
      if (k < keep) {
        significant.push_back(members[k]);
      } else {
        set_fate(members[k], -1, "not highest in cell");
      }
    }
  }
  result.significant = static_cast<int>(significant.size());

  struct Candidates {
    int rock_a = -1;
    int model_best = -1;  // Index into eb.rocks / q_in_a.
    int pattern[2] = {-1, -1};
    int votes[2] = {0, 0};
    double cost[2] = {0.0, 0.0};  // PairCost (eq. 3.28) of each pattern candidate.
  };
  std::vector<Candidates> per_rock;
  std::vector<CandidateVector> vectors;
  int terrain_rejects = 0;
  for (int i : significant) {
    const ExtractedRock& p = a.rocks[i];
    Candidates c;
    c.rock_a = i;
    const double radius = SearchRadius(p.peak, camera_b_in_a, prior, options);
    q_grid.ForEachNear(p.peak.head<2>(), radius, [&](int j) {
      if ((q_in_a[j] - p.peak).head<2>().norm() > radius) return;
      const int votes = count_votes(p.peak - q_in_a[j]);
      if (votes > c.votes[0] || (votes == c.votes[0] && c.pattern[0] >= 0 && j < c.pattern[0])) {
        c.votes[1] = c.votes[0];
        c.pattern[1] = c.pattern[0];
        c.votes[0] = votes;
        c.pattern[0] = j;
      } else if (votes > c.votes[1] || c.pattern[1] < 0) {
        c.votes[1] = votes;
        c.pattern[1] = j;
      }
    });
    if (c.pattern[0] < 0) {  // No candidate near this rock.
      set_fate(i, -1, "no candidate");
      continue;
    }
    // Model matching among the two pattern candidates (Fig. 3.3: local pattern matching limits
    // model matching to two candidates).
    double best_cost = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 2; ++k) {
      if (c.pattern[k] < 0) continue;
      const ExtractedRock& q = b.rocks[eb.rocks[c.pattern[k]]];
      const double cost = PairCost(p, q, options);
      c.cost[k] = cost;
      if (cost < best_cost) {
        best_cost = cost;
        c.model_best = c.pattern[k];
      }
    }
    if (best_cost <= options.max_model_cost) {
      const ExtractedRock& q = b.rocks[eb.rocks[c.model_best]];
      const double angle = NormalAngleDeg(p.plane_normal, rotation_a_from_b * q.plane_normal);
      const bool terrain_ok = angle <= fd.max_normal_angle_deg;
      terrain_rejects += terrain_ok ? 0 : 1;
      result.model_matches += terrain_ok ? 1 : 0;
    } else {
      c.model_best = -1;
    }
    for (int k = 0; k < 2; ++k) {
      if (c.pattern[k] < 0) continue;
      vectors.push_back(
          {static_cast<int>(per_rock.size()), p.peak - q_in_a[c.pattern[k]], q_in_a[c.pattern[k]]});
    }
    per_rock.push_back(c);
  }
  result.global_translation =
      GlobalTranslation(vectors, options.consensus_translation, options.max_vector_deviation_m);
  report.Add(RockCount("III matching", "local terrain mismatch (plane normals)", terrain_rejects,
                       fd.max_normal_angle_deg, "deg"));

  // Global pattern consistency, then the combination of both methods. A candidate's V deviates
  // from the V the pattern expects there (the global V, turned with consensus_turn) by the two
  // peaks' errors plus the prior's heading error acting on the rock's distance from site a (kept
  // in full with the turn: a bound, not an estimate); the candidate nearer by that covariance
  // wins.
  const PatternMotion motion =
      options.consensus_turn
          ? FitPatternMotion(vectors, result.global_translation, options.max_vector_deviation_m,
                             options.consensus_turn_trim_m,
                             3.0 * prior.heading_sigma_deg / kRadToDeg)
          : PatternMotion{result.global_translation};
  result.global_turn_deg = motion.turn_rad * kRadToDeg;
  // A pair's V from the one the pattern expects there (both rocks in a's frame).
  const auto pattern_deviation = [&](const Eigen::Vector3d& pa, const Eigen::Vector3d& qa) {
    return Eigen::Vector3d(pa - qa - motion.ExpectedV(qa));
  };
  const auto deviation_of = [&](const ExtractedRock& p, int candidate) {
    return pattern_deviation(p.peak, q_in_a[candidate]);
  };
  const auto heading_lever = [&](const ExtractedRock& p) {
    return prior.heading_sigma_deg / kRadToDeg * (p.peak - a.camera_center).head<2>().norm();
  };
  const auto deviation_chi2 = [&](const ExtractedRock& p, int candidate) {
    const double lever = heading_lever(p);
    const Eigen::Matrix3d cov = p.peak_covariance + covariance_b_in_a[candidate] +
                                lever * lever * Eigen::Matrix3d::Identity();
    const Eigen::Vector3d deviation = deviation_of(p, candidate);
    return deviation.dot(cov.ldlt().solve(deviation));
  };
  std::vector<RockMatch> combined;
  for (const Candidates& c : per_rock) {
    const ExtractedRock& p = a.rocks[c.rock_a];
    int winner = c.pattern[0];
    double chi2 = deviation_chi2(p, winner);
    if (c.pattern[1] >= 0) {
      const double chi2_second = deviation_chi2(p, c.pattern[1]);
      if (chi2_second < chi2) {
        winner = c.pattern[1];
        chi2 = chi2_second;
      }
    }
    const auto inconsistent = [&](int candidate, double candidate_chi2) {
      return deviation_of(p, candidate).norm() > options.max_vector_deviation_m ||
             candidate_chi2 > options.max_vector_chi2;
    };
    if (inconsistent(winner, chi2)) {
      set_fate(c.rock_a, eb.rocks[winner], "inconsistent vector");
      continue;
    }
    ++result.pattern_matches;
    const int k = winner == c.pattern[0] ? 0 : 1;  // The winner's pattern slot.
    // The global pattern vouches for the winner where it puts b's rock within
    // pattern_vouch_deviation_m of where the other rocks say it should be, with enough votes.
    const bool vouched = options.pattern_vouch_deviation_m > 0.0 &&
                         c.votes[k] >= options.pattern_vouch_votes &&
                         deviation_of(p, winner).norm() <= options.pattern_vouch_deviation_m;
    // A rock that, put in the place of either rock of a pair the pattern vouches for, moves V
    // beyond pattern_vouch_deviation_m plus ambiguity_sigmas sigmas of the new pair's peaks from
    // the V the pattern expects there is no alternative to that pair
    // (pattern_vouch_rules_out_alternatives).
    const bool rules_out = vouched && options.pattern_vouch_rules_out_alternatives;
    const auto off_pattern = [&](const Eigen::Vector3d& pa, const Eigen::Vector3d& qa,
                                 const Eigen::Matrix2d& covariance) {
      return !EllipticGate::ToleranceAndSigmas(covariance, options.pattern_vouch_deviation_m,
                                               options.ambiguity_sigmas)
                  .Contains(pattern_deviation(pa, qa).head<2>());
    };
    if (c.model_best < 0 && !vouched) {
      set_fate(c.rock_a, eb.rocks[winner], "model cost");
      continue;
    }
    if (c.model_best >= 0 && winner != c.model_best) {
      // The model prefers the other pattern candidate. Where the global pattern excludes that one
      // (the bounds that would have excluded it as the winner), it is no alternative, and the
      // winner is judged as a lone candidate is: by its own model cost and terrain.
      const bool settled =
          (options.pattern_settles_disagreement &&
           inconsistent(c.model_best, deviation_chi2(p, c.model_best)) &&
           c.cost[k] <= options.max_model_cost) ||
          (rules_out && off_pattern(p.peak, q_in_a[c.model_best],
                                    HorizontalCovariance(p) + spread_b[c.model_best].covariance));
      if (!settled) {
        set_fate(c.rock_a, eb.rocks[winner], "methods disagree");
        continue;
      }
    }
    const ExtractedRock& q = b.rocks[eb.rocks[winner]];
    const double normal_angle = NormalAngleDeg(p.plane_normal, rotation_a_from_b * q.plane_normal);
    if (normal_angle > fd.max_normal_angle_deg) {
      set_fate(c.rock_a, eb.rocks[winner], "terrain mismatch");
      continue;
    }
    if (!vouched && std::max(p.height_m, q.height_m) < options.low_pair_max_height_m &&
        std::max(LargestHorizontalSigma(p), spread_b[winner].largest_sigma) >
            options.low_rock_max_peak_sigma_m) {
      set_fate(c.rock_a, eb.rocks[winner], "low rock seen from afar");
      continue;
    }
    // The partner's covariance in the tested site's frame, with the prior's heading error: a
    // neighbour that the heading can swap with the rock is no better than one the peaks can.
    const double lever = heading_lever(p);
    const Eigen::Matrix2d heading = lever * lever * Eigen::Matrix2d::Identity();
    const std::function<bool(int)> alternative_b = [&](int j) {
      return !off_pattern(
          p.peak, a_from_b_prior * b.rocks[j].peak,
          HorizontalCovariance(p) + HorizontalCovariance(b.rocks[j], rotation_a_from_b));
    };
    const std::function<bool(int)> alternative_a = [&](int i) {
      return !off_pattern(a.rocks[i].peak, q_in_a[winner],
                          HorizontalCovariance(a.rocks[i]) + spread_b[winner].covariance);
    };
    if (ambiguous_b.Ambiguous(eb.rocks[winner],
                              HorizontalCovariance(p, rotation_a_from_b.transpose()) + heading,
                              rules_out ? alternative_b : nullptr)) {
      ++ambiguous;
      set_fate(c.rock_a, eb.rocks[winner], "ambiguous at b");
      continue;
    }
    // The same test at a with the partner's covariance: a far (imprecise) peak of b can as well be
    // a neighbour of p within its uncertainty.
    if (ambiguous_a.Ambiguous(c.rock_a, spread_b[winner].covariance + heading,
                              rules_out ? alternative_a : nullptr)) {
      ++ambiguous;
      set_fate(c.rock_a, eb.rocks[winner], "ambiguous at a");
      continue;
    }
    RockMatch m;
    m.rock_a = c.rock_a;
    m.rock_b = eb.rocks[winner];
    m.model_cost = c.cost[k];
    m.pattern_count = c.votes[k];
    m.normal_angle_deg = normal_angle;
    m.distance_ratio = DistanceRatio(p.peak, a.camera_center, camera_b_in_a);
    combined.push_back(m);
  }
  // Multiple matches: keep the lowest model cost for each rock of b.
  std::sort(combined.begin(), combined.end(), [](const RockMatch& x, const RockMatch& y) {
    return x.model_cost != y.model_cost ? x.model_cost < y.model_cost : x.rock_a < y.rock_a;
  });
  std::vector<char> taken(b.rocks.size(), 0);
  int multiples = 0;
  for (const RockMatch& m : combined) {
    if (taken[m.rock_b]) {
      ++multiples;
      set_fate(m.rock_a, m.rock_b, "multiple match");
      continue;
    }
    taken[m.rock_b] = 1;
    result.matches.push_back(m);
  }
  std::sort(result.matches.begin(), result.matches.end(),
            [](const RockMatch& x, const RockMatch& y) { return x.rock_a < y.rock_a; });
  report.Add(RockCount("III matching", "multiple matches of one rock", multiples, 1, "rocks"));
  report.Add(RockCount("III matching", "ambiguous rock (neighbour within tolerance + k sigma)",
                       ambiguous, options.pattern_tolerance_m, "m"));

  // A tie point's covariance at either site: the peak's stereo covariance plus the horizontal
  // peak definition, times the variance factor (the fit, its outlier test, RE and the output).
  const auto tie_covariance = [&](const ExtractedRock& rock) {
    Eigen::Matrix3d c = rock.peak_covariance;
    c.topLeftCorner<2, 2>() += options.peak_definition_sigma_m * options.peak_definition_sigma_m *
                               Eigen::Matrix2d::Identity();
    return Eigen::Matrix3d(options.tie_variance_factor * c);
  };
  // The match as a tie point: both peaks in their site frames with those covariances.
  const auto tie_point = [&](const RockMatch& m) {
    const ExtractedRock& p = a.rocks[m.rock_a];
    const ExtractedRock& q = b.rocks[m.rock_b];
    TiePoint t;
    char id[64];
    std::snprintf(id, sizeof(id), "s%03d-s%03d-r%d", a.site, b.site, p.id);
    t.id = id;
    t.site_a = a.site;
    t.site_b = b.site;
    t.position_in_a = p.peak;
    t.covariance_in_a = tie_covariance(p);
    t.position_in_b = q.peak;
    t.covariance_in_b = tie_covariance(q);
    t.source = "rock";
    return t;
  };
  const auto planar_tie = [&](const RockMatch& m) { return PlanarTie(tie_point(m)); };
  // Outlier test in the site-to-site adjustment (data snooping): with redundancy left, the tie
  // point that disagrees most with the conformal fit (eq. 4.4) of the others, if its chi-square
  // exceeds `max_residual_chi2` (LeaveOneOutChi2), is dropped and the test repeated.
  int outliers = 0;
  while (static_cast<int>(result.matches.size()) > fd.min_tie_points) {
    std::vector<PlanarTiePoint> ties;
    for (const RockMatch& m : result.matches) ties.push_back(planar_tie(m));
    const std::vector<double> chi2 = LeaveOneOutChi2(ties);
    size_t worst = 0;
    double worst_chi2 = 0.0;
    for (size_t k = 0; k < chi2.size(); ++k) {
      if (chi2[k] > worst_chi2) {  // NaN (the others not fittable) never is
        worst_chi2 = chi2[k];
        worst = k;
      }
    }
    if (worst_chi2 <= options.max_residual_chi2) break;
    set_fate(result.matches[worst].rock_a, result.matches[worst].rock_b, "residual outlier");
    result.matches.erase(result.matches.begin() + static_cast<long>(worst));
    ++outliers;
  }
  for (const RockMatch& m : result.matches) set_fate(m.rock_a, m.rock_b, "matched");
  report.Add(RockCount("IV adjustment", "tie point residual outlier (conformal fit)", outliers,
                       options.max_residual_chi2, "chi2"));

  // IV: pair-level rules before the bundle adjustment.
  double ratio_sum = 0.0;
  std::vector<PlanarTiePoint> planar;
  for (const RockMatch& m : result.matches) {
    ratio_sum += m.distance_ratio;
    planar.push_back(planar_tie(m));
  }
  const double mean_ratio =
      result.matches.empty() ? 0.0 : ratio_sum / static_cast<double>(result.matches.size());
  report.Add(MinCheck("III peaks", "averaged distance ratio of the matched rocks", mean_ratio,
                      fd.min_pair_distance_ratio, ""));
  report.Add(MinCheck("IV adjustment", "number of tie points",
                      static_cast<double>(result.matches.size()), fd.min_tie_points, "points"));
  if (static_cast<int>(planar.size()) >= 2) {
    result.error = EvaluateSitePair(planar, a_from_b_prior.translation.head<2>());
  }
  if (result.error) {
    report.Add(MaxCheck("IV adjustment", "relative error RE (eq. 4.9)",
                        result.error->relative_error_percent, fd.max_relative_error_percent, "%"));
  } else if (planar.size() >= 2) {
    // Tie points the conformal fit cannot adjust (degenerate, or not converging): RE unknown,
    // and a leg is never accepted without it.
    report.Add({"IV adjustment", "relative error RE (eq. 4.9)", std::nan(""),
                fd.max_relative_error_percent, "%", FaultVerdict::kFail, true});
  } else {
    report.Add({"IV adjustment", "relative error RE (eq. 4.9)", std::nan(""),
                fd.max_relative_error_percent, "%", FaultVerdict::kNotEvaluated, false});
  }
  if (report.outcome != PairOutcome::kMatched) return result;
  for (const RockMatch& m : result.matches) result.tie_points.push_back(tie_point(m));
  return result;
}

}  // namespace areomap
