#include "areomap/landmarks/rock_matching.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include <gtest/gtest.h>
#include <Eigen/Dense>
#include <nlohmann/json.hpp>

#include "areomap/map/error.h"
#include "areomap/samples/simulated_points.h"

namespace areomap {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Scene RockyScene(uint32_t seed) {
  SceneOptions options;
  options.half_extent_m = 60.0;
  options.crater_count = 0;
  options.roughness_m = 0.3;
  options.rock_path = {Eigen::Vector2d(-30, 0), Eigen::Vector2d(30, 0)};
  options.rock_abundance_k = 0.08;
  options.rock_corridor_m = 15.0;
  options.seed = seed;
  return Scene(options);
}

struct SimulatedSite {
  Eigen::Vector2d enu;
  double ground = 0.0;
  SiteRocks rocks;
};

// A site's rocks from a simulated stereo cloud (eq. 4.3 noise) over the given azimuths.
SimulatedSite MakeSite(const Scene& scene, const Eigen::Vector2d& enu, int id, double az_min,
                       double az_max) {
  SimulatedPointsOptions sim;
  sim.azimuth_min_deg = az_min;
  sim.azimuth_max_deg = az_max;
  sim.max_range_m = 14.0;
  sim.angular_step_rad = 2e-3;
  sim.seed = static_cast<uint32_t>(id) + 10u;
  const PointCloud cloud = SimulateSitePointCloud(scene, enu, id, sim);
  SimulatedSite site;
  site.enu = enu;
  site.ground = scene.GroundHeightAt(enu.x(), enu.y());
  site.rocks.site = id;
  site.rocks.camera_center = cloud.camera_center;
  site.rocks.rocks = ExtractRocks(cloud, {});
  return site;
}

// The true rock under a site-frame peak: the nearest footprint within 0.5 m among the rocks at
// least 10 cm high (a pebble cannot make a peak 15 cm above its ground), or -1.
int TrueRock(const Scene& scene, const SimulatedSite& site, const Eigen::Vector3d& peak) {
  const Eigen::Vector2d enu = site.enu + Eigen::Vector2d(peak.y(), peak.x());
  return scene.RockNear(enu, 0.10, 0.5);
}

// Site b's true pose in a (site frames share their axes) with a telemetry-like error: 1.5 degree
// heading and ~0.5 m position.
Rigid3d TelemetryPrior(const SimulatedSite& a, const SimulatedSite& b) {
  const Eigen::Vector2d d = b.enu - a.enu;
  const Eigen::Vector3d truth(d.y(), d.x(), -(b.ground - a.ground));
  return Rigid3d(Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d::UnitZ()).matrix(),
                 truth + Eigen::Vector3d(0.4, -0.3, 0.05));
}

// Two sites 12 m apart looking at each other, and a third beside b looking away from a; each
// cloud is simulated once per test process, on first use (they dominate the run time).
const Scene& SharedScene() {
  static const Scene scene = RockyScene(5);
  return scene;
}
const SimulatedSite& SiteA() {
  static const SimulatedSite site = MakeSite(SharedScene(), {-6.0, 0.0}, 1, 20.0, 160.0);
  return site;
}
const SimulatedSite& SiteB() {
  static const SimulatedSite site = MakeSite(SharedScene(), {6.0, 0.0}, 2, 200.0, 340.0);
  return site;
}
const SimulatedSite& SiteLookingAway() {
  static const SimulatedSite site = MakeSite(SharedScene(), {6.0, 0.0}, 2, 30.0, 150.0);
  return site;
}

// Sites a and b matched under the telemetry-like prior.
SitePairMatch MatchSitesAAndB(const RockMatchingOptions& options = {}) {
  return MatchSitePair(SiteA().rocks, SiteB().rocks, TelemetryPrior(SiteA(), SiteB()), options);
}

TEST(RockMatching, TwoSitesTwelveMetresApartGiveCorrectTiePoints) {
  const Scene& scene = SharedScene();
  const SimulatedSite& a = SiteA();
  const SimulatedSite& b = SiteB();
  const SitePairMatch match = MatchSitesAAndB();
  EXPECT_EQ(match.report.outcome, PairOutcome::kMatched) << match.report.ToText();
  ASSERT_GE(match.tie_points.size(), 3u) << match.report.ToText();
  ASSERT_EQ(match.tie_points.size(), match.matches.size());
  int same_rock = 0;
  for (size_t k = 0; k < match.matches.size(); ++k) {
    const RockMatch& m = match.matches[k];
    const TiePoint& t = match.tie_points[k];
    EXPECT_EQ(t.site_a, 1);
    EXPECT_EQ(t.site_b, 2);
    const int truth_a = TrueRock(scene, a, t.position_in_a);
    const int truth_b = TrueRock(scene, b, t.position_in_b);
    same_rock += truth_a >= 0 && truth_a == truth_b ? 1 : 0;
    // The two measurements agree in the scene within the tie point's covariance (eq. 4.3 plus
    // the peak-definition term): chi-square with 2 degrees of freedom below its 99.9 % point.
    const Eigen::Vector2d pa = a.enu + Eigen::Vector2d(t.position_in_a.y(), t.position_in_a.x());
    const Eigen::Vector2d pb = b.enu + Eigen::Vector2d(t.position_in_b.y(), t.position_in_b.x());
    Eigen::Matrix2d cov = (t.covariance_in_a + t.covariance_in_b).topLeftCorner<2, 2>();
    std::swap(cov(0, 0), cov(1, 1));  // North-east to east-north.
    const Eigen::Vector2d e = pa - pb;
    EXPECT_LT(e.dot(cov.inverse() * e), 13.8) << t.id << " |e| " << e.norm();
    EXPECT_LE(m.model_cost, RockMatchingOptions{}.max_model_cost);
  }
  // Tie-point precision against the scene's rocks (a wrong match is a defect).
  EXPECT_EQ(same_rock, static_cast<int>(match.matches.size()));
  ASSERT_TRUE(match.error.has_value());
  EXPECT_LT(match.error->relative_error_percent, 2.0);
  const FaultCheck* count = match.report.Find("number of tie points");
  ASSERT_NE(count, nullptr);
  EXPECT_EQ(count->verdict, FaultVerdict::kPass);
}

TEST(RockMatching, TieVarianceFactorScalesTheTieCovariancesAndRe) {
  // The outlier test is off: the factor would change its verdicts, not only the covariances.
  RockMatchingOptions options;
  options.max_residual_chi2 = 1e9;
  const SitePairMatch base = MatchSitesAAndB(options);
  ASSERT_TRUE(base.error.has_value());
  ASSERT_GE(base.tie_points.size(), 3u);
  options.tie_variance_factor = 0.5;
  const SitePairMatch scaled = MatchSitesAAndB(options);
  ASSERT_TRUE(scaled.error.has_value());
  ASSERT_EQ(scaled.tie_points.size(), base.tie_points.size());
  for (size_t k = 0; k < base.tie_points.size(); ++k) {
    EXPECT_EQ(scaled.tie_points[k].id, base.tie_points[k].id);
    EXPECT_TRUE(scaled.tie_points[k].covariance_in_a.isApprox(
        0.5 * base.tie_points[k].covariance_in_a, 1e-12));
    EXPECT_TRUE(scaled.tie_points[k].covariance_in_b.isApprox(
        0.5 * base.tie_points[k].covariance_in_b, 1e-12));
  }
  // The fit is the same; its covariance halves (RE / sqrt 2) and its chi-square doubles.
  EXPECT_NEAR(scaled.error->relative_error_percent,
              std::sqrt(0.5) * base.error->relative_error_percent,
              1e-6 * base.error->relative_error_percent);
  EXPECT_NEAR(scaled.error->chi2, 2.0 * base.error->chi2, 1e-6 * base.error->chi2 + 1e-12);
  EXPECT_EQ(scaled.error->redundancy, base.error->redundancy);
  options.tie_variance_factor = 0.0;
  EXPECT_THROW(MatchSitesAAndB(options), Error);
}

TEST(RockMatching, PairsWithoutOverlapOrRocksAreExcludedWithAReport) {
  const SimulatedSite& a = SiteA();
  // Site b looks away from a: no common rocks, so fault detection excludes the pair.
  const SimulatedSite& away = SiteLookingAway();
  const SitePairMatch none = MatchSitePair(a.rocks, away.rocks, TelemetryPrior(a, away), {});
  EXPECT_EQ(none.report.outcome, PairOutcome::kExcludedByFaultDetection) << none.report.ToText();
  EXPECT_TRUE(none.tie_points.empty());
  // Too far apart: pre-screening (traverse > 30 m).
  SimulatedSite far = away;
  far.enu = Eigen::Vector2d(40.0, 0.0);
  const SitePairMatch distant = MatchSitePair(a.rocks, far.rocks, TelemetryPrior(a, far), {});
  EXPECT_EQ(distant.report.outcome, PairOutcome::kExcludedByPreScreening);
  EXPECT_EQ(distant.report.Find("traverse length")->verdict, FaultVerdict::kFail);
  // A site without rocks: pre-screening (< 10 peaks).
  SiteRocks empty;
  empty.site = 3;
  const SitePairMatch rockless = MatchSitePair(a.rocks, empty, TelemetryPrior(a, away), {});
  EXPECT_EQ(rockless.report.outcome, PairOutcome::kExcludedByPreScreening);
  EXPECT_EQ(rockless.report.Find("peaks at site b")->verdict, FaultVerdict::kFail);
  EXPECT_TRUE(rockless.tie_points.empty());
}

TEST(RockMatching, ReportListsEveryRuleWithValueThresholdAndVerdict) {
  SiteRocks a, b;
  a.site = 1;
  b.site = 2;
  const SitePairMatch match =
      MatchSitePair(a, b, Rigid3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(10, 0, 0)), {});
  // Pre-screening stops at Module II with empty sites; the stereo rules are "not evaluated".
  EXPECT_EQ(match.report.Find("matching correlation coefficient")->verdict,
            FaultVerdict::kNotEvaluated);
  const nlohmann::json json = match.report.ToJson();
  EXPECT_EQ(json["outcome_code"], 2);
  EXPECT_EQ(json["rules"].size(), match.report.checks.size());
  // With stereo statistics the Module II rules are evaluated.
  const SitePairMatch with_stereo =
      MatchSitePair(a, b, Rigid3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(10, 0, 0)), {},
                    StereoQuality{0.80, 1.0});
  EXPECT_EQ(with_stereo.report.Find("matching correlation coefficient")->verdict,
            FaultVerdict::kFail);
  EXPECT_EQ(with_stereo.report.Find("vertical disparity")->verdict, FaultVerdict::kPass);
  EXPECT_NE(with_stereo.report.ToText().find("excluded by pre-screening"), std::string::npos);
}

// A prior with its sigmas bounds the search: the true pose stated precisely gives the same correct
// tie points; the same pose 2 m off but claiming 0.1 m / 0.5 degree cannot reach the partners
// (the 2.5 m radius of a bare prior would), so it matches nothing rather than something wrong.
TEST(RockMatching, PriorSigmaBoundsTheSearch) {
  const Scene& scene = SharedScene();
  const SimulatedSite& a = SiteA();
  const SimulatedSite& b = SiteB();
  const Eigen::Vector2d d = b.enu - a.enu;
  RockMatchingPrior precise;
  precise.a_from_b =
      Rigid3d(Eigen::Matrix3d::Identity(), Eigen::Vector3d(d.y(), d.x(), -(b.ground - a.ground)));
  precise.position_sigma_m = 0.1;
  precise.heading_sigma_deg = 0.5;
  precise.source = "orbital registration";
  const SitePairMatch match = MatchSitePair(a.rocks, b.rocks, precise, {});
  EXPECT_EQ(match.report.outcome, PairOutcome::kMatched) << match.report.ToText();
  ASSERT_GE(match.tie_points.size(), 3u) << match.report.ToText();
  for (const TiePoint& t : match.tie_points) {
    const int truth_a = TrueRock(scene, a, t.position_in_a);
    EXPECT_GE(truth_a, 0) << t.id;
    EXPECT_EQ(truth_a, TrueRock(scene, b, t.position_in_b)) << t.id;
  }
  RockMatchingPrior off = precise;
  off.a_from_b.translation += Eigen::Vector3d(2.0, 0.0, 0.0);
  const SitePairMatch none = MatchSitePair(a.rocks, b.rocks, off, {});
  EXPECT_TRUE(none.tie_points.empty()) << none.report.ToText();
  EXPECT_NE(none.report.outcome, PairOutcome::kMatched);
  off.position_sigma_m = std::nan("");
  EXPECT_THROW(MatchSitePair(a.rocks, b.rocks, off, {}), Error);
}

TEST(RockMatching, ModelCostIsEq328) {
  RockModelParameters p, q;
  p.height = q.height = 0.3;
  p.a = p.b = q.a = q.b = 0.4;
  EXPECT_DOUBLE_EQ(ModelMatchCost(p, q, {}), 0.0);
  q.height = 0.6;  // Height differs by 2/3 of the mean; radius equal; area differs too.
  const double area = 2.0 * std::abs(p.SurfaceAreaExact() - q.SurfaceAreaExact()) /
                      (p.SurfaceAreaExact() + q.SurfaceAreaExact());
  EXPECT_NEAR(ModelMatchCost(p, q, {}), 0.5 * (0.3 / 0.45) + area / 6.0, 1e-12);
  RockMatchingOptions bad;
  bad.pattern_tolerance_m = 0.0;
  EXPECT_THROW(MatchSitePair({}, {}, Rigid3d(), bad), Error);
  bad = RockMatchingOptions{};
  bad.fault_detection.min_tie_points = 1;
  EXPECT_THROW(MatchSitePair({}, {}, Rigid3d(), bad), Error);
  bad = RockMatchingOptions{};
  bad.pattern_vouch_votes = 0;
  EXPECT_THROW(MatchSitePair({}, {}, Rigid3d(), bad), Error);
  bad = RockMatchingOptions{};
  bad.pattern_vouch_deviation_m = -0.1;
  EXPECT_THROW(MatchSitePair({}, {}, Rigid3d(), bad), Error);
  bad = RockMatchingOptions{};
  bad.consensus_turn_trim_m = 0.0;
  EXPECT_THROW(MatchSitePair({}, {}, Rigid3d(), bad), Error);
}

// A modeled rock at `peak` (site frame) with an isotropic horizontal peak sigma [m], its model
// fitted to `points` surface points (the default: enough for eq. 3.28).
ExtractedRock ModeledRock(int id, const Eigen::Vector3d& peak, double height, double sigma,
                          int points = 80) {
  ExtractedRock r;
  r.id = id;
  r.peak = peak;
  r.peak_covariance = Eigen::Vector3d(sigma * sigma, sigma * sigma, 0.01 * 0.01).asDiagonal();
  r.range_m = peak.head<2>().norm();
  r.height_m = height;
  r.peak_foot = peak + Eigen::Vector3d(0, 0, height);
  r.surface_indices.resize(static_cast<size_t>(points));
  std::iota(r.surface_indices.begin(), r.surface_indices.end(), 0);
  RockModelFit fit;
  fit.converged = true;
  fit.parameters.height = height;
  fit.parameters.a = fit.parameters.b = 0.25;
  r.models = {fit};
  return r;
}

// Nine rocks beyond the peak range, so that a site passes pre-screening (>= 10 peaks).
void AddPrescreeningFillers(SiteRocks* site) {
  for (int k = 0; k < 9; ++k) {
    site->rocks.push_back(ModeledRock(10 + k, {0.0, -31.0 - k, 0}, 0.2, 0.05));
  }
}

TEST(RockMatching, CheckRockRulesNamesTheFirstFailingRule) {
  const Eigen::Vector3d own = Eigen::Vector3d::Zero(), other(20.0, 0.0, 0.0);
  const RockMatchingOptions options;
  EXPECT_EQ(CheckRockRules(ModeledRock(1, {10, 2, 0}, 0.2, 0.1), own, other, options),
            RockRule::kEligible);
  EXPECT_EQ(CheckRockRules(ModeledRock(1, {31, 0, 0}, 0.2, 0.1), own, other, options),
            RockRule::kBeyondRange);
  const double just_under = options.fault_detection.min_peak_to_plane_m - 0.01;
  EXPECT_EQ(CheckRockRules(ModeledRock(1, {10, 2, 0}, just_under, 0.1), own, other, options),
            RockRule::kTooLow);
  ExtractedRock unmodeled = ModeledRock(1, {10, 2, 0}, 0.2, 0.1);
  unmodeled.models.clear();
  EXPECT_EQ(CheckRockRules(unmodeled, own, other, options), RockRule::kFewPoints);
  ExtractedRock big = ModeledRock(1, {10, 2, 0}, 0.2, 0.1);
  big.models.front().parameters.height = 1.5;
  EXPECT_EQ(CheckRockRules(big, own, other, options), RockRule::kImplausible);
  // Distance ratio (Fig. 4.19): 2 m from its own camera, 18 m from the other.
  EXPECT_EQ(CheckRockRules(ModeledRock(1, {2, 0, 0}, 0.2, 0.1), own, other, options),
            RockRule::kLowRatio);
  EXPECT_EQ(CheckRockRules(ModeledRock(1, {10, 2, 0}, 0.2, 0.7), own, other, options),
            RockRule::kImprecise);
  EXPECT_EQ(ToString(RockRule::kImprecise), "peak sigma");
}

// Two sites 12 m apart along north, each camera 1.5 m above its origin, matched with the true pose
// as prior. `rocks_a` and `rocks_b` are in their own site's frame; the pre-screening fillers are
// added to both. A rock 6 m north of a is at kRockInA in a and kRockInA - kCameraBInA in b.
const Eigen::Vector3d kCameraBInA(12.0, 0.0, 0.0), kRockInA(6.0, 1.0, 0.0);

SitePairMatch MatchTwelveMetrePair(std::vector<ExtractedRock> rocks_a,
                                   std::vector<ExtractedRock> rocks_b,
                                   const RockMatchingOptions& options = {}) {
  SiteRocks a, b;
  a.site = 1;
  b.site = 2;
  b.camera_center = a.camera_center = Eigen::Vector3d(0, 0, -1.5);
  a.rocks = std::move(rocks_a);
  b.rocks = std::move(rocks_b);
  AddPrescreeningFillers(&a);
  AddPrescreeningFillers(&b);
  return MatchSitePair(a, b, Rigid3d(Eigen::Quaterniond::Identity(), kCameraBInA), options);
}

// What became of site a's first rock ("not eligible" when it never reached the matching).
std::string FateOfFirstRockOfA(const SitePairMatch& match) {
  for (const RockMatchOutcome& o : match.outcomes) {
    if (o.rock_a == 0) return o.fate;
  }
  return "not eligible";
}

bool AnyAmbiguousAtA(const SitePairMatch& match) {
  return std::any_of(match.outcomes.begin(), match.outcomes.end(),
                     [](const RockMatchOutcome& o) { return o.fate == "ambiguous at a"; });
}

// Site a sees two rocks 0.9 m apart sharply (5 cm); site b sees only one of them, from far
// (0.5 m sigma). Its peak could be either rock of a: the match is ambiguous at a and dropped,
// whatever the pattern says.
TEST(RockMatching, FarPeakNearTwoRocksOfTheOtherSiteIsAmbiguous) {
  const ExtractedRock rock = ModeledRock(1, kRockInA, 0.30, 0.05);
  const ExtractedRock far = ModeledRock(1, kRockInA - kCameraBInA, 0.30, 0.5);
  const SitePairMatch match = MatchTwelveMetrePair(
      {rock, ModeledRock(2, kRockInA + Eigen::Vector3d(0.9, 0, 0), 0.25, 0.05)}, {far});
  EXPECT_TRUE(match.matches.empty());
  ASSERT_FALSE(match.outcomes.empty());
  EXPECT_TRUE(AnyAmbiguousAtA(match));
  // The same far peak next to a single rock of a is matched.
  const SitePairMatch single = MatchTwelveMetrePair({rock}, {far});
  ASSERT_EQ(single.matches.size(), 1u);
  ASSERT_EQ(single.outcomes.size(), 1u);
  EXPECT_EQ(single.outcomes.front().fate, "matched");
  EXPECT_EQ(single.outcomes.front().rock_b, 0);
}

// A far stereo peak is uncertain along its line of sight (eq. 4.3: range error ~ r^2) and precise
// across it (azimuth error ~ r). Site b's peak has 0.5 m of range sigma and 2 cm across: a second
// rock of a 0.9 m beside the first, across b's line of sight, is told apart by the bearing; the
// same rock 0.9 m behind the first, along it, is not.
TEST(RockMatching, FarPeakIsAmbiguousAlongItsLineOfSightOnly) {
  const Eigen::Vector2d sight = (kRockInA - kCameraBInA).head<2>().normalized();
  const Eigen::Vector2d across(-sight.y(), sight.x());
  ExtractedRock far = ModeledRock(1, kRockInA - kCameraBInA, 0.30, 0.0);
  far.peak_covariance.topLeftCorner<2, 2>() =
      0.5 * 0.5 * sight * sight.transpose() + 0.02 * 0.02 * across * across.transpose();
  const auto match_with_neighbour_at = [&](const Eigen::Vector2d& offset,
                                           const RockMatchingOptions& options = {}) {
    return MatchTwelveMetrePair(
        {ModeledRock(1, kRockInA, 0.30, 0.05),
         ModeledRock(2, kRockInA + Eigen::Vector3d(offset.x(), offset.y(), 0), 0.25, 0.05)},
        {far}, options);
  };
  const SitePairMatch beside = match_with_neighbour_at(0.9 * across);
  ASSERT_EQ(beside.matches.size(), 1u);
  EXPECT_EQ(beside.matches.front().rock_a, 0);
  EXPECT_EQ(beside.matches.front().rock_b, 0);
  const SitePairMatch behind = match_with_neighbour_at(0.9 * sight);
  EXPECT_TRUE(behind.matches.empty());
  EXPECT_TRUE(AnyAmbiguousAtA(behind));
  // A prior whose heading is known to 10 degrees only can swap the rock with its neighbour beside
  // it (10 degrees at 6 m: 1 m): ambiguous as well.
  RockMatchingOptions loose_heading;
  loose_heading.prior_heading_sigma_deg = 10.0;
  EXPECT_TRUE(match_with_neighbour_at(0.9 * across, loose_heading).matches.empty());
}

// A rock measured just under the 15 cm rule at one site may be over it at the other, so a
// neighbour of about the tested rock's height counts from 10 cm up; a low bump beside a taller
// rock, or a neighbour lower than 10 cm, does not.
TEST(RockMatching, LowNeighbourOfTheRocksOwnHeightMakesItAmbiguous) {
  const auto fate_with_neighbour = [](double rock_height, double neighbour_height,
                                      const RockMatchingOptions& options = {}) {
    return FateOfFirstRockOfA(MatchTwelveMetrePair(
        {ModeledRock(1, kRockInA, rock_height, 0.05),
         ModeledRock(2, kRockInA + Eigen::Vector3d(0.4, 0.2, 0), neighbour_height, 0.05)},
        {ModeledRock(1, kRockInA - kCameraBInA, rock_height, 0.05)}, options));
  };
  EXPECT_EQ(fate_with_neighbour(0.17, 0.13), "ambiguous at a");  // |dh| / mean 0.27.
  EXPECT_EQ(fate_with_neighbour(0.17, 0.09), "matched");         // Under 10 cm.
  EXPECT_EQ(fate_with_neighbour(0.30, 0.12), "matched");         // |dh| / mean 0.86.
  EXPECT_EQ(fate_with_neighbour(0.17, 0.16), "ambiguous at a");  // Over 15 cm: always.
  RockMatchingOptions tall_only;  // The rule before 2026-12-04: neighbours from 15 cm only.
  tall_only.ambiguity_similar_min_height_m = tall_only.ambiguity_min_height_m;
  EXPECT_EQ(fate_with_neighbour(0.17, 0.13, tall_only), "matched");
}

TEST(RockMatching, SignificantRocksAreTheThreeHighestOfTheirCell) {
  // Ch. 3.2 keeps the highest rock of each grid cell; three per 3 m cell keep more rocks of a
  // in play, and each rock left out is lower than three rocks of its cell that are in play.
  const SimulatedSite& a = SiteA();
  RockMatchingOptions one;
  one.significant_per_cell = 1;
  const SitePairMatch single = MatchSitesAAndB(one);
  const SitePairMatch three = MatchSitesAAndB();
  EXPECT_GT(three.significant, single.significant);
  EXPECT_GE(three.matches.size(), single.matches.size());
  const double cell = RockMatchingOptions{}.significant_cell_m;
  const auto cell_of = [&](int rock) {
    const Eigen::Vector3d& p = a.rocks.rocks[static_cast<size_t>(rock)].peak;
    return std::make_pair(std::floor(p.x() / cell), std::floor(p.y() / cell));
  };
  int left_out = 0;
  for (const RockMatchOutcome& o : three.outcomes) {
    if (o.fate != "not highest in cell") continue;
    ++left_out;
    const double height = a.rocks.rocks[static_cast<size_t>(o.rock_a)].height_m;
    int higher_in_play = 0;
    for (const RockMatchOutcome& other : three.outcomes) {
      if (other.rock_a == o.rock_a || other.fate == "not highest in cell" ||
          other.fate == "ambiguous at a" || cell_of(other.rock_a) != cell_of(o.rock_a)) {
        continue;
      }
      higher_in_play += a.rocks.rocks[static_cast<size_t>(other.rock_a)].height_m >= height;
    }
    EXPECT_EQ(higher_in_play, 3) << "rock " << o.rock_a;
  }
  int left_out_single = 0;
  for (const RockMatchOutcome& o : single.outcomes) {
    left_out_single += o.fate == "not highest in cell" ? 1 : 0;
  }
  EXPECT_GE(left_out, 1);  // The scene has a cell with four rocks in play.
  EXPECT_LT(left_out, left_out_single);
}

// A pair of two rocks under 16 cm (the 12 cm rule admits them) is matched only while both peaks
// are precise: a far peak of a low rock has look-alike neighbours too low to be extracted, which
// the ambiguity test cannot see. A pair with one rock from 16 cm up is not low. (A lone rock: no
// pattern vouches for it, PatternVouchesForALowPairSeenFromAfar.)
TEST(RockMatching, LowPairIsMatchedOnlyBetweenPrecisePeaks) {
  const RockMatchingOptions twelve_cm;  // The default.
  ASSERT_EQ(twelve_cm.fault_detection.min_peak_to_plane_m, 0.12);
  const auto fate = [](double height_a, double height_b, double sigma_b,
                       const RockMatchingOptions& options) {
    return FateOfFirstRockOfA(
        MatchTwelveMetrePair({ModeledRock(1, kRockInA, height_a, 0.05)},
                             {ModeledRock(1, kRockInA - kCameraBInA, height_b, sigma_b)}, options));
  };
  EXPECT_EQ(fate(0.13, 0.13, 0.05, twelve_cm), "matched");
  EXPECT_EQ(fate(0.13, 0.13, 0.25, twelve_cm), "matched");
  EXPECT_EQ(fate(0.13, 0.13, 0.40, twelve_cm), "low rock seen from afar");
  EXPECT_EQ(fate(0.15, 0.15, 0.40, twelve_cm), "low rock seen from afar");
  EXPECT_EQ(fate(0.17, 0.17, 0.40, twelve_cm), "matched");  // Not low.
  // Measured under 15 cm at one site, from 16 cm up at the other: not a low pair.
  EXPECT_EQ(fate(0.13, 0.165, 0.40, twelve_cm), "matched");
  EXPECT_EQ(fate(0.165, 0.13, 0.40, twelve_cm), "matched");
  // A bound above both rocks: the pair is low, as every pair with a rock under 15 cm was before
  // 2026-12-05.
  RockMatchingOptions higher_bound = twelve_cm;
  higher_bound.low_pair_max_height_m = 0.20;
  EXPECT_EQ(fate(0.13, 0.165, 0.40, higher_bound), "low rock seen from afar");
  RockMatchingOptions loose = twelve_cm;
  loose.low_rock_max_peak_sigma_m = 0.5;
  EXPECT_EQ(fate(0.13, 0.13, 0.40, loose), "matched");
  RockMatchingOptions fifteen_cm;
  fifteen_cm.fault_detection.min_peak_to_plane_m = 0.15;
  EXPECT_EQ(fate(0.13, 0.13, 0.40, fifteen_cm), "not eligible");
}

// The fate of rock 1 of a (height_a, peak sigma 0.05 m) whose partner at b (height_b, sigma_b)
// lies `partner_offset` from its true place, among `others` (0-4) rocks of 0.25-0.28 m seen alike
// at both sites 3-4 m around it, which set the global pattern.
// `extra_a`, `extra_b`: further rocks of either site, in site a's frame (b's are shifted by the
// prior's translation).
std::string FateAmongPatternRocks(double height_a, double height_b, double sigma_b, int others,
                                  const Eigen::Vector3d& partner_offset,
                                  const RockMatchingOptions& options,
                                  const std::vector<ExtractedRock>& extra_a = {},
                                  std::vector<ExtractedRock> extra_b = {}) {
  const std::vector<Eigen::Vector3d> around = {{3, 3, 0}, {-3, 3, 0}, {3, -3, 0}, {-2.5, -3, 0}};
  std::vector<ExtractedRock> at_a = {ModeledRock(1, kRockInA, height_a, 0.05)};
  std::vector<ExtractedRock> at_b = {
      ModeledRock(1, kRockInA - kCameraBInA + partner_offset, height_b, sigma_b)};
  at_a.insert(at_a.end(), extra_a.begin(), extra_a.end());
  for (ExtractedRock& r : extra_b) r.peak -= kCameraBInA;
  at_b.insert(at_b.end(), extra_b.begin(), extra_b.end());
  for (int k = 0; k < others; ++k) {
    const double height = 0.25 + 0.01 * k;
    at_a.push_back(ModeledRock(2 + k, kRockInA + around[k], height, 0.05));
    at_b.push_back(ModeledRock(2 + k, kRockInA + around[k] - kCameraBInA, height, 0.05));
  }
  return FateOfFirstRockOfA(MatchTwelveMetrePair(at_a, at_b, options));
}

// A low pair seen from afar is matched when the global pattern vouches for it: its V within
// pattern_vouch_deviation_m (0.2 m) of the global V, and at least pattern_vouch_votes (3) rocks
// voting for it. Rocks of 0.25-0.28 m 3 m around it set the pattern.
TEST(RockMatching, PatternVouchesForALowPairSeenFromAfar) {
  const auto fate = [](int others, const Eigen::Vector3d& partner_offset,
                       const RockMatchingOptions& options) {
    return FateAmongPatternRocks(0.13, 0.13, 0.40, others, partner_offset, options);
  };
  const RockMatchingOptions defaults;
  ASSERT_EQ(defaults.pattern_vouch_deviation_m, 0.2);
  ASSERT_EQ(defaults.pattern_vouch_votes, 3);
  const Eigen::Vector3d on_pattern = Eigen::Vector3d::Zero();
  EXPECT_EQ(fate(4, on_pattern, defaults), "matched");
  EXPECT_EQ(fate(2, on_pattern, defaults), "matched");  // Three votes.
  EXPECT_EQ(fate(2, Eigen::Vector3d(0.15, 0, 0), defaults), "matched");
  // Two votes: a pattern of two rocks does not vouch (a lone rock's V is the global V).
  EXPECT_EQ(fate(1, on_pattern, defaults), "low rock seen from afar");
  EXPECT_EQ(fate(0, on_pattern, defaults), "low rock seen from afar");
  // 0.3 m off the pattern, within the global test's bounds (1 m) but not the vouching's.
  EXPECT_EQ(fate(4, Eigen::Vector3d(0.3, 0, 0), defaults), "low rock seen from afar");
  EXPECT_EQ(fate(4, Eigen::Vector3d(0, -0.3, 0), defaults), "low rock seen from afar");
  RockMatchingOptions wider = defaults;
  wider.pattern_vouch_deviation_m = 0.35;
  EXPECT_EQ(fate(4, Eigen::Vector3d(0.3, 0, 0), wider), "matched");
  RockMatchingOptions never = defaults;
  never.pattern_vouch_deviation_m = 0.0;
  EXPECT_EQ(fate(4, on_pattern, never), "low rock seen from afar");
  RockMatchingOptions more_votes = defaults;
  more_votes.pattern_vouch_votes = 5;
  EXPECT_EQ(fate(2, on_pattern, more_votes), "low rock seen from afar");
  EXPECT_EQ(fate(4, on_pattern, more_votes), "matched");
}

// The pattern vouches against the pair cost too: a rock measured 0.40 m high at a and 0.26 m at b
// (a 42 % difference, cost 0.84 > 0.6; a far view measures a rock low) is matched where the
// pattern puts its partner, not 0.3 m off it nor without three votes.
TEST(RockMatching, PatternVouchesForAPairOfUnequalHeights) {
  const auto fate = [](int others, const Eigen::Vector3d& partner_offset,
                       const RockMatchingOptions& options) {
    return FateAmongPatternRocks(0.40, 0.26, 0.20, others, partner_offset, options);
  };
  const RockMatchingOptions defaults;
  ASSERT_GT(PairCost(ModeledRock(1, kRockInA, 0.40, 0.05), ModeledRock(1, kRockInA, 0.26, 0.05),
                     defaults),
            defaults.max_model_cost);
  const Eigen::Vector3d on_pattern = Eigen::Vector3d::Zero();
  EXPECT_EQ(fate(4, on_pattern, defaults), "matched");
  EXPECT_EQ(fate(2, on_pattern, defaults), "matched");
  EXPECT_EQ(fate(1, on_pattern, defaults), "model cost");
  EXPECT_EQ(fate(4, Eigen::Vector3d(0.3, 0, 0), defaults), "model cost");
  RockMatchingOptions never = defaults;
  never.pattern_vouch_deviation_m = 0.0;
  EXPECT_EQ(fate(4, on_pattern, never), "model cost");
}

// A neighbour 0.75 m from either rock of a pair, as high as they: within the ambiguity test's gate
// (0.6 m plus a sigma of the peaks and of the prior's 2 degree heading error 6 m from site a,
// 0.22 m), so the pair is ambiguous unless the pattern vouches for it. Put in the place of the
// rock, the neighbour would move V 0.75 m off the global V, beyond pattern_vouch_deviation_m
// (0.2 m) plus a sigma of the peaks (0.07 m): it is no alternative. One 0.25 m away still is.
TEST(RockMatching, PatternRulesOutAlternativesToAPairItVouchesFor) {
  const RockMatchingOptions defaults;
  ASSERT_TRUE(defaults.pattern_vouch_rules_out_alternatives);
  RockMatchingOptions off = defaults;
  off.pattern_vouch_rules_out_alternatives = false;
  for (const bool at_b : {true, false}) {
    const auto fate = [&](int others, double neighbour_m, const RockMatchingOptions& options) {
      const std::vector<ExtractedRock> neighbour = {
          ModeledRock(9, kRockInA + Eigen::Vector3d(neighbour_m, 0, 0), 0.25, 0.05)};
      return FateAmongPatternRocks(0.25, 0.25, 0.05, others, Eigen::Vector3d::Zero(), options,
                                   at_b ? std::vector<ExtractedRock>{} : neighbour,
                                   at_b ? neighbour : std::vector<ExtractedRock>{});
    };
    const std::string ambiguous = at_b ? "ambiguous at b" : "ambiguous at a";
    SCOPED_TRACE(ambiguous);
    EXPECT_EQ(fate(4, 0.75, defaults), "matched");
    EXPECT_EQ(fate(4, 0.75, off), ambiguous);
    EXPECT_EQ(fate(4, 0.25, defaults), ambiguous);
    // Two votes: no vouching, the neighbour counts.
    EXPECT_EQ(fate(1, 0.75, defaults), ambiguous);
  }
}

// The prior's heading is off by 3 degrees: b's rocks, put in a by the prior, lie turned about b's
// camera, and a pair's V changes across the scene by 5 cm per metre. A low rock seen from afar
// 9 m from a pattern of five rocks has its V 0.47 m from the global V, beyond the vouching's
// 0.2 m: it is not vouched for. The pattern's turn, fitted to the rocks' V, puts it back on the
// pattern (consensus_turn). A turn beyond three sigmas of the prior's heading is not believed.
TEST(RockMatching, ConsensusTurnMeasuresThePriorsHeadingError) {
  const Eigen::Matrix3d true_turn =
      Eigen::AngleAxisd(3.0 * kDeg, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto in_b = [&](const Eigen::Vector3d& in_a) {
    return Eigen::Vector3d(true_turn.transpose() * (in_a - kCameraBInA));
  };
  const Eigen::Vector3d far_rock(6, 6, 0);
  std::vector<ExtractedRock> at_a = {ModeledRock(1, far_rock, 0.13, 0.05)};
  std::vector<ExtractedRock> at_b = {ModeledRock(1, in_b(far_rock), 0.13, 0.40)};
  const std::vector<Eigen::Vector3d> pattern = {
      {3, -5, 0}, {9, -5, 0}, {3, -1, 0}, {9, -1, 0}, {6, -3, 0}};
  for (size_t k = 0; k < pattern.size(); ++k) {
    const double height = 0.25 + 0.01 * static_cast<double>(k);
    at_a.push_back(ModeledRock(2 + static_cast<int>(k), pattern[k], height, 0.05));
    at_b.push_back(ModeledRock(2 + static_cast<int>(k), in_b(pattern[k]), height, 0.05));
  }
  const RockMatchingOptions turned;
  ASSERT_TRUE(turned.consensus_turn);
  const SitePairMatch with_turn = MatchTwelveMetrePair(at_a, at_b, turned);
  EXPECT_NEAR(with_turn.global_turn_deg, 3.0, 0.05);
  EXPECT_EQ(FateOfFirstRockOfA(with_turn), "matched");
  RockMatchingOptions translation_only = turned;
  translation_only.consensus_turn = false;
  const SitePairMatch without = MatchTwelveMetrePair(at_a, at_b, translation_only);
  EXPECT_EQ(without.global_turn_deg, 0.0);
  EXPECT_EQ(FateOfFirstRockOfA(without), "low rock seen from afar");
  RockMatchingOptions tight_prior = turned;
  tight_prior.prior_heading_sigma_deg = 0.5;
  EXPECT_EQ(MatchTwelveMetrePair(at_a, at_b, tight_prior).global_turn_deg, 0.0);
}

// Model matching prefers a look-alike of site b 1.5 m from where the pattern puts the rock's
// partner (measured heights 0.30 and 0.30 m: cost 0, against the partner's 0.25 m: 0.36): the
// global pattern excludes that look-alike as it would exclude it as the winner, so it is no
// alternative, and the partner is matched as a lone candidate would be. Not when the option is off
// (ch. 3.2: both methods must agree), nor when the partner's own cost is above the limit.
TEST(RockMatching, PatternSettlesADisagreementWhenTheModelsChoiceIsOffThePattern) {
  // Four rocks seen alike at both sites set the pattern (the median V).
  std::vector<ExtractedRock> a_rocks, b_rocks;
  const std::vector<Eigen::Vector3d> others = {{3, 3, 0}, {-3, 3, 0}, {3, -3, 0}, {-2.5, -3, 0}};
  for (size_t k = 0; k < others.size(); ++k) {
    const int id = 2 + static_cast<int>(k);
    const double height = 0.25 + 0.03 * static_cast<double>(k);
    a_rocks.push_back(ModeledRock(id, kRockInA + others[k], height, 0.05));
    b_rocks.push_back(ModeledRock(id, kRockInA + others[k] - kCameraBInA, height, 0.05));
  }
  const auto fate = [&](double partner_height, double partner_radius,
                        const RockMatchingOptions& options) {
    std::vector<ExtractedRock> at_a = a_rocks, at_b = b_rocks;
    at_a.insert(at_a.begin(), ModeledRock(1, kRockInA, 0.30, 0.05));
    ExtractedRock partner = ModeledRock(1, kRockInA - kCameraBInA, partner_height, 0.05);
    partner.models.front().parameters.a = partner.models.front().parameters.b = partner_radius;
    at_b.push_back(partner);
    at_b.push_back(ModeledRock(9, kRockInA - kCameraBInA + Eigen::Vector3d(0, 1.5, 0), 0.30, 0.05));
    const SitePairMatch match = MatchTwelveMetrePair(at_a, at_b, options);
    for (const RockMatchOutcome& o : match.outcomes) {
      if (o.rock_a == 0) {
        return o.fate + (o.rock_b >= 0 ? " " + std::to_string(at_b[o.rock_b].id) : "");
      }
    }
    return std::string("not eligible");
  };
  // The partner's V is the global V with five votes: the pattern vouches for it, and rules the
  // look-alike out on its own (PatternRulesOutAlternativesToAPairItVouchesFor); here the rule of
  // pattern_settles_disagreement alone.
  const RockMatchingOptions defaults;
  ASSERT_TRUE(defaults.pattern_vouch_rules_out_alternatives);
  RockMatchingOptions settles = defaults;
  settles.pattern_vouch_rules_out_alternatives = false;
  ASSERT_TRUE(settles.pattern_settles_disagreement);
  EXPECT_EQ(fate(0.25, 0.25, settles), "matched 1");
  RockMatchingOptions off = settles;
  off.pattern_settles_disagreement = false;
  EXPECT_EQ(fate(0.25, 0.25, off), "methods disagree 1");
  RockMatchingOptions vouch_only = defaults;
  vouch_only.pattern_settles_disagreement = false;
  EXPECT_EQ(fate(0.25, 0.25, vouch_only), "matched 1");
  // A pair the pattern vouches for is exempt from the cost limit too.
  EXPECT_EQ(fate(0.16, 0.25, defaults), "matched 1");
  // Height 0.16 against 0.30: cost above 0.6.
  EXPECT_EQ(fate(0.16, 0.25, settles), "methods disagree 1");
  // Eq. 3.28 also weighs the models' radii: 0.9 against 0.25 m costs above 0.6 there, not by
  // the measured heights.
  EXPECT_EQ(fate(0.25, 0.9, settles), "matched 1");
  RockMatchingOptions models = settles;
  models.compare_models = true;
  EXPECT_EQ(fate(0.25, 0.25, models), "matched 1");
  EXPECT_EQ(fate(0.25, 0.9, models), "methods disagree 1");
}

// Three rocks whose partners lie 1.8 m from where the prior puts them, each with a decoy of site b
// near the prior's place: the median of the six candidate vectors falls half-way, 1.1 m from the
// true pattern, and the deviation test drops every true partner (ch. 3.2's median). The consensus
// of the three rocks is the true translation, and all three are matched.
TEST(RockMatching, ConsensusTranslationFindsThePatternThatFewRocksAgreeOn) {
  const Eigen::Vector3d prior_error(0.3, 1.8, 0.0);  // V of the true partners.
  const std::vector<Eigen::Vector3d> in_a = {kRockInA, kRockInA + Eigen::Vector3d(-2, 3.5, 0),
                                             kRockInA + Eigen::Vector3d(2, -3.5, 0)};
  const std::vector<Eigen::Vector3d> decoy_v = {{0.8, -0.4, 0}, {-0.8, -0.4, 0}, {0, -1.3, 0}};
  std::vector<ExtractedRock> a_rocks, b_rocks;
  for (size_t k = 0; k < in_a.size(); ++k) {
    const int id = 1 + static_cast<int>(k);
    a_rocks.push_back(ModeledRock(id, in_a[k], 0.25, 0.05));
    b_rocks.push_back(ModeledRock(id, in_a[k] - kCameraBInA - prior_error, 0.25, 0.05));
    b_rocks.push_back(ModeledRock(20 + id, in_a[k] - kCameraBInA - decoy_v[k], 0.25, 0.05));
  }
  const auto fates = [&](const RockMatchingOptions& options, Eigen::Vector3d* translation) {
    const SitePairMatch match = MatchTwelveMetrePair(a_rocks, b_rocks, options);
    *translation = match.global_translation;
    std::vector<std::string> out(in_a.size(), "not eligible");
    for (const RockMatchOutcome& o : match.outcomes) {
      if (o.rock_a >= static_cast<int>(in_a.size())) continue;
      out[o.rock_a] = o.fate;
      // Every fate names the true partner as the judged candidate.
      EXPECT_EQ(o.rock_b, 2 * o.rock_a) << o.fate;
    }
    return out;
  };
  const RockMatchingOptions consensus;
  ASSERT_TRUE(consensus.consensus_translation);
  Eigen::Vector3d translation;
  EXPECT_EQ(fates(consensus, &translation), std::vector<std::string>(3, "matched"));
  EXPECT_LT((translation - prior_error).norm(), 1e-9);
  RockMatchingOptions median = consensus;
  median.consensus_translation = false;
  EXPECT_EQ(fates(median, &translation), std::vector<std::string>(3, "inconsistent vector"));
  EXPECT_NEAR(translation.x(), 0.3, 1e-9);
  EXPECT_NEAR(translation.y(), 0.7, 1e-9);
}

// A far peak whose model rests on 12 (or 80) surface points has a mean radius of 0.06 m where the
// near site's model has 0.35 m: eq. 3.28 costs more than 0.6 and would drop the true partner. By
// default the pair is compared by its measured heights (0.20 and 0.18 m): matched, while a
// look-alike of 0.13 m (42 % lower) is refused. With compare_models, eq. 3.28 decides where both
// models rest on min_shape_points or more, and with min_shape_points 0 for every pair (ch. 3.2).
TEST(RockMatching, PairsAreComparedByTheirMeasuredHeightsUnlessModelsAreAskedFor) {
  const auto fate = [](double far_height, int far_points, const RockMatchingOptions& options) {
    ExtractedRock near = ModeledRock(1, kRockInA, 0.20, 0.05);
    near.models.front().parameters.a = near.models.front().parameters.b = 0.35;
    ExtractedRock far = ModeledRock(1, kRockInA - kCameraBInA, far_height, 0.25, far_points);
    far.models.front().parameters.a = far.models.front().parameters.b = 0.06;
    return FateOfFirstRockOfA(MatchTwelveMetrePair({near}, {far}, options));
  };
  const RockMatchingOptions options;
  ASSERT_FALSE(options.compare_models);
  EXPECT_EQ(fate(0.18, 12, options), "matched");
  EXPECT_EQ(fate(0.18, 80, options), "matched");
  EXPECT_EQ(fate(0.13, 12, options), "model cost");
  EXPECT_EQ(fate(0.13, 80, options), "model cost");
  RockMatchingOptions models = options;
  models.compare_models = true;
  ASSERT_EQ(models.min_shape_points, 40);
  EXPECT_EQ(fate(0.18, 12, models), "matched");     // A model from 12 points: the heights.
  EXPECT_EQ(fate(0.18, 80, models), "model cost");  // Both models determined: eq. 3.28.
  RockMatchingOptions models_always = models;
  models_always.min_shape_points = 0;
  EXPECT_EQ(fate(0.18, 12, models_always), "model cost");
  // The cost itself: max_model_cost at the "same size" limit of the ambiguity test (30 %).
  const ExtractedRock a = ModeledRock(1, kRockInA, 0.20, 0.05, 10);
  const ExtractedRock b = ModeledRock(2, kRockInA, 0.20 * 1.15 / 0.85, 0.05, 10);
  EXPECT_NEAR(PairCost(a, b, options), options.max_model_cost, 1e-12);
  EXPECT_NEAR(PairCost(a, a, options), 0.0, 1e-12);
}

TEST(RockMatching, OutcomesAccountForEveryMatch) {
  const SitePairMatch match = MatchSitesAAndB();
  int matched = 0;
  std::vector<int> seen;
  for (const RockMatchOutcome& o : match.outcomes) {
    EXPECT_EQ(std::count(seen.begin(), seen.end(), o.rock_a), 0) << "rock " << o.rock_a;
    seen.push_back(o.rock_a);
    EXPECT_FALSE(o.fate.empty());
    if (o.fate != "matched") continue;
    ++matched;
    const bool listed = std::any_of(
        match.matches.begin(), match.matches.end(),
        [&](const RockMatch& m) { return m.rock_a == o.rock_a && m.rock_b == o.rock_b; });
    EXPECT_TRUE(listed) << "rock " << o.rock_a;
  }
  EXPECT_EQ(matched, static_cast<int>(match.matches.size()));
}

}  // namespace
}  // namespace areomap
