// Where a generated mission's rocks are lost on the way to tie points: per leg of a finished
// `areomap run`, the truth rocks at least as high as fault detection's peak-to-plane limit that
// both sites could give as tie points, stage by stage:
//   overlap   within max_peak_range_m (horizontal) of both true cameras
//   ratio     distance ratio (Fig. 4.19) >= the per-rock limit
//   seen      >= 5 points of each site's cloud within 80 % of the rock's footprint
//   peaks     an extracted rock's peak on it at both sites (rock_truth.h)
//   eligible  that rock passes every per-rock rule (CheckRockRules) at both sites; the rocks that
//             do not are counted under the first rule failing at either site
//   matched   a rock match of the run (matches.csv, by rock id) joins the two peaks
//   accepted  ... and fault detection accepted the leg (tie points)
// Rocks are re-extracted from each site's points.ply with the run's default options (extraction
// is deterministic, so the ids are the run's). The other site's camera comes from the truth.
//
// When the leg's unit.json records its prior pose (prior.a_from_b_*), the leg is re-matched here
// with that prior (MatchSitePair), which also tells what became of each eligible rock that was not
// matched (RockMatchOutcome), and lets `NAME=VALUE` arguments try other matching options; the
// outcome column then names the pair-level rules that excluded the leg, with their values.
// Then the legs' test of `areomap run` (TestLegConsistency) on the accepted legs' tie points:
// what it drops, and the accepted tie points left, right or wrong by the same truth rule.
// Every match is also judged by the sight ray (bench::SightRayTruth: the truth rock the camera's
// ray through each peak meets), which follows a far peak along its line of sight where the disk
// rule gives it to the tallest rock nearby; both verdicts are printed, with how often each calls a
// decoy right (the match's site-a peak with the site-b peak nearest its partner).
//
// Like `areomap run`, the legs are then matched again at the variance factor the first pass's
// conformal fits show (MissionRunOptions::rock_variance_pass; `rock_variance_pass=0` turns it
// off): the second pass's table follows the first's.
//
// Each table ends with the eligible rocks lost in the matching, by fate, and how many of them the
// matching judged with their true partner as the candidate (what a looser rule at that step could
// gain); an excluded leg lists its own. Then how often the pair cost (PairCost) passes an eligible
// rock's true partner and an eligible look-alike of site b within 1.5 m of it, compared by the
// measured heights and by the models (eq. 3.28). `truth_prior_position_sigma_m=S
// truth_prior_heading_sigma_deg=D` searches each leg around the true pose with those sigmas instead
// of the run's prior: an upper bound on what a better prior (the adjusted poses, say) could give.
//
// Run: build/ci/bench/areomap_bench_rock_funnel MISSION_DIR RUN_DIR [ROCKS_CSV] [NAME=VALUE...]
// ROCKS_CSV (optional): one row per truth rock past the ratio stage and site of the leg, with the
// nearest extracted peak, its height and rule, its elevation error and its horizontal offset from
// the rock's centre along and across the line of sight, for a closer look at the losses.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/landmarks/leg_consistency.h"
#include "areomap/landmarks/localization_error.h"
#include "areomap/landmarks/rock_matching.h"
#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/pipeline/mission_run.h"
#include "rock_truth.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;
using bench::TruthRock;

constexpr int kRules = 7;  // RockRule values.

struct Site {
  Eigen::Vector3d camera_world = Eigen::Vector3d::Zero();
  std::vector<ExtractedRock> rocks;
  std::map<int, int> points_on_rock;         // Truth id -> cloud points within 80 % footprint.
  std::map<int, std::vector<int>> rocks_on;  // Truth id -> indices of extracted rocks on it.
  std::vector<std::vector<int>> could_make;  // Per extracted rock: bench::RocksThatCouldMake.
  std::vector<int> seen_on;                  // Per extracted rock: bench::SightRayTruth, or -1.
  std::map<int, int> id_to_index;            // ExtractedRock::id -> index.
  std::vector<Eigen::Vector2d> peaks_world;
  std::vector<double> peak_z_world,
      foot_z_world;  // Down, in site 0's frame [m].  // Extracted peaks in site 0's frame.
};

// How often the disk rule (bench::RockUnder) and the sight ray (bench::SightRayTruth) name the
// same truth rock (or none) for an extracted peak, for peaks with a largest horizontal sigma below
// and above 0.1 m.
struct VerdictAgreement {
  std::array<int, 2> peaks{}, agree{};
};

// The sites as LoadSite made them, kept for the second pass (loaded on first use), and the
// verdicts' agreement over them.
struct LoadedSites {
  std::vector<std::optional<Site>> sites;  // One per mission site.
  VerdictAgreement agreement;
};

Site LoadSite(const fs::path& run_dir, int site, const Rigid3d& world_from_site,
              const std::vector<TruthRock>& truth, const bench::SightRayTruth& sight,
              const MissionRunOptions& options, VerdictAgreement* agreement) {
  char name[32];
  std::snprintf(name, sizeof(name), "sites/site_%03d", site);
  const PointCloud cloud = ReadPointCloudPly(run_dir / name / "points.ply");
  Site s;
  s.camera_world = world_from_site * cloud.camera_center;
  s.rocks = ExtractRocks(cloud, options.rocks);
  // Truth rocks near the site on a 1 m hash grid.
  const auto key = [](const Eigen::Vector2d& p) {
    return (static_cast<long long>(std::floor(p.x())) << 32) ^
           (static_cast<long long>(std::floor(p.y())) & 0xffffffffLL);
  };
  std::unordered_map<long long, std::vector<int>> cells;
  const double min_height = options.matching.fault_detection.min_peak_to_plane_m;
  for (size_t i = 0; i < truth.size(); ++i) {
    const TruthRock& r = truth[i];
    if (r.height < min_height || (r.north_east - s.camera_world.head<2>()).norm() > 35.0) continue;
    const double reach = 0.8 * r.radius;
    for (double x = std::floor(r.north_east.x() - reach); x <= r.north_east.x() + reach; x += 1.0) {
      for (double y = std::floor(r.north_east.y() - reach); y <= r.north_east.y() + reach;
           y += 1.0) {
        cells[key(Eigen::Vector2d(x, y))].push_back(static_cast<int>(i));
      }
    }
  }
  for (const StereoPoint& p : cloud.points) {
    const Eigen::Vector2d w = (world_from_site * p.position).head<2>();
    const auto it = cells.find(key(w));
    if (it == cells.end()) continue;
    for (int i : it->second) {
      if ((truth[i].north_east - w).norm() <= 0.8 * truth[i].radius)
        ++s.points_on_rock[truth[i].id];
    }
  }
  const Eigen::Matrix2d turn = world_from_site.RotationMatrix().topLeftCorner<2, 2>();
  for (size_t k = 0; k < s.rocks.size(); ++k) {
    const ExtractedRock& r = s.rocks[k];
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(
        r.peak_covariance.topLeftCorner<2, 2>());
    const double sigma = std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
    const Eigen::Vector3d peak_world = world_from_site * r.peak;
    const int id = bench::RockUnder(truth, peak_world.head<2>(), sigma);
    if (id >= 0) s.rocks_on[id].push_back(static_cast<int>(k));
    const Eigen::Matrix2d covariance_world =
        turn * r.peak_covariance.topLeftCorner<2, 2>() * turn.transpose();
    s.could_make.push_back(
        bench::RocksThatCouldMake(truth, peak_world.head<2>(), covariance_world, r.height_m));
    s.seen_on.push_back(sight.RockSeen(s.camera_world, peak_world, sigma));
    const int precision = sigma < 0.1 ? 0 : 1;
    ++agreement->peaks[precision];
    agreement->agree[precision] += s.seen_on.back() == id ? 1 : 0;
    s.peaks_world.push_back(peak_world.head<2>());
    s.peak_z_world.push_back(peak_world.z());
    s.foot_z_world.push_back((world_from_site * r.peak_foot).z());
    s.id_to_index[r.id] = static_cast<int>(k);
  }
  return s;
}

// The best rule verdict among the extracted rocks on one truth rock (eligible beats any failure;
// otherwise the latest rule in the order, i.e. the rock that got furthest).
RockRule BestRule(const Site& s, int truth_id, const Eigen::Vector3d& own,
                  const Eigen::Vector3d& other, const RockMatchingOptions& options, int* index) {
  RockRule best = RockRule::kBeyondRange;
  *index = -1;
  for (int k : s.rocks_on.at(truth_id)) {
    const RockRule rule = CheckRockRules(s.rocks[k], own, other, options);
    const auto rank = [](RockRule r) {
      return r == RockRule::kEligible ? 100 : static_cast<int>(r);
    };
    if (*index < 0 || rank(rule) > rank(best)) {
      best = rule;
      *index = k;
    }
  }
  return best;
}

struct Funnel {
  int overlap = 0, ratio = 0, seen = 0, peaks = 0, eligible = 0, matched = 0, accepted = 0;
  std::array<int, kRules> failed{};
  int wrong_matches = 0, wrong_accepted = 0, leg_matches = 0;
  // Matches whose peaks the sight ray (bench::SightRayTruth) puts on two rocks or on none.
  int wrong_by_sight = 0, wrong_by_sight_accepted = 0;
  // A check of both verdicts: each match's site-a peak paired instead with the site-b peak
  // nearest to its partner (within 1.5 m), a plausible wrong match; how often each verdict
  // calls that pair right (it can be: two peaks on one large rock).
  int decoys = 0, decoys_right_by_disk = 0, decoys_right_by_sight = 0;
  // Matches whose peaks no single truth rock could have made (bench::RocksThatCouldMake).
  int no_common_rock = 0, no_common_rock_accepted = 0;
  std::map<std::string, int> lost_in_matching;  // Eligible at both, not matched: why.
  // ... of which the candidate the matching judged (RockMatchOutcome::rock_b) was the true partner.
  std::map<std::string, int> lost_with_true_candidate;
};

// The prior the run's leg unit used (unit.json "prior"), when it recorded the pose.
std::optional<RockMatchingPrior> RecordedPrior(const nlohmann::json& prior) {
  if (!prior.contains("a_from_b_translation_m")) return std::nullopt;
  RockMatchingPrior out;
  const std::vector<double> t = prior["a_from_b_translation_m"].get<std::vector<double>>();
  const double turn = prior.value("a_from_b_turn_deg", 0.0) * std::numbers::pi / 180.0;
  out.a_from_b = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ())),
                         Eigen::Vector3d(t.at(0), t.at(1), t.at(2)));
  out.position_sigma_m = prior.value("position_sigma_m", 0.0);
  out.heading_sigma_deg = prior.value("heading_sigma_deg", 0.0);
  out.source = prior.value("source", std::string("telemetry"));
  return out;
}

// What-if of the prior: each leg searched around the true pose of site b in site a, with these
// sigmas, in place of the prior its run recorded (an upper bound on what a better prior, e.g. the
// adjusted poses, could give). Off while truth_prior_position_sigma_m < 0.
struct TruthPrior {
  double position_sigma_m = -1.0;
  double heading_sigma_deg = 0.0;
};

// NAME=VALUE overrides of the run's default options (what-if experiments).
void ApplyOverride(const std::string& text, MissionRunOptions* options, TruthPrior* truth_prior) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos) throw Error("'" + text + "': expected NAME=VALUE");
  const std::string name = text.substr(0, eq);
  const double value = std::stod(text.substr(eq + 1));
  RockMatchingOptions& m = options->matching;
  FaultDetectionOptions& fd = m.fault_detection;
  const std::map<std::string, double*> doubles = {
      {"max_peak_sigma_m", &m.max_peak_sigma_m},
      {"low_rock_max_peak_sigma_m", &m.low_rock_max_peak_sigma_m},
      {"low_pair_max_height_m", &m.low_pair_max_height_m},
      {"pattern_vouch_deviation_m", &m.pattern_vouch_deviation_m},
      {"pattern_tolerance_m", &m.pattern_tolerance_m},
      {"max_model_cost", &m.max_model_cost},
      {"significant_cell_m", &m.significant_cell_m},
      {"ambiguity_sigmas", &m.ambiguity_sigmas},
      {"ambiguity_min_height_m", &m.ambiguity_min_height_m},
      {"ambiguity_similar_min_height_m", &m.ambiguity_similar_min_height_m},
      {"ambiguity_similar_height_difference", &m.ambiguity_similar_height_difference},
      {"peak_definition_sigma_m", &m.peak_definition_sigma_m},
      {"max_vector_deviation_m", &m.max_vector_deviation_m},
      {"max_vector_chi2", &m.max_vector_chi2},
      {"consensus_turn_trim_m", &m.consensus_turn_trim_m},
      {"tie_variance_factor", &m.tie_variance_factor},
      {"min_peak_to_plane_m", &fd.min_peak_to_plane_m},
      {"max_relative_error_percent", &fd.max_relative_error_percent},
      {"max_normal_angle_deg", &fd.max_normal_angle_deg},
      {"model_min_height_m", &options->rocks.model_min_height_m},
      {"plane_exclusion_k", &options->rocks.plane_exclusion_k},
      {"min_height_m", &options->rocks.min_height_m}};
  if (name == "truth_prior_position_sigma_m") {
    truth_prior->position_sigma_m = value;
  } else if (name == "truth_prior_heading_sigma_deg") {
    truth_prior->heading_sigma_deg = value;
  } else if (name == "consensus_turn") {
    options->matching.consensus_turn = value != 0.0;
  } else if (name == "pattern_vouch_rules_out_alternatives") {
    options->matching.pattern_vouch_rules_out_alternatives = value != 0.0;
  } else if (name == "pattern_settles_disagreement") {
    options->matching.pattern_settles_disagreement = value != 0.0;
  } else if (name == "compare_models") {
    options->matching.compare_models = value != 0.0;
  } else if (name == "consensus_translation") {
    options->matching.consensus_translation = value != 0.0;
  } else if (name == "rock_variance_pass") {
    options->rock_variance_pass = value != 0.0;
  } else if (name == "min_shape_points") {
    m.min_shape_points = static_cast<int>(value);
  } else if (name == "pattern_vouch_votes") {
    m.pattern_vouch_votes = static_cast<int>(value);
  } else if (name == "significant_per_cell") {
    m.significant_per_cell = static_cast<int>(value);
  } else if (name == "min_surface_points") {
    fd.min_surface_points = static_cast<int>(value);
  } else if (doubles.count(name)) {
    *doubles.at(name) = value;
  } else {
    throw Error("'" + name + "': not an option this bench can change");
  }
}

// What `areomap run` does next (TestLegConsistency): the legs it changes, and the accepted tie
// points it leaves, by the truth of the matches behind them.
// Whether a match joins one truth rock, by the disk rule and by the sight ray.
struct MatchTruth {
  bool disk = false, sight = false;
};

void PrintLegTest(const std::vector<std::vector<TiePoint>>& leg_ties,
                  const std::vector<std::map<int, MatchTruth>>& truth_by_rock_a,
                  const LegConsistencyOptions& test) {
  const std::vector<LegConsistency> verdicts = TestLegConsistency(leg_ties, test);
  const auto truth = [&](size_t leg, const TiePoint& t) {
    const auto it = truth_by_rock_a[leg].find(bench::RockIdOfTie(t.id));
    return it != truth_by_rock_a[leg].end() ? it->second : MatchTruth{};
  };
  const auto right = [&](size_t leg, const TiePoint& t) { return truth(leg, t).disk; };
  int kept = 0, kept_right = 0, kept_seen_right = 0, legs_kept = 0;
  for (size_t k = 0; k < leg_ties.size(); ++k) {
    const LegConsistency& v = verdicts[k];
    if (!v.dropped.empty() || v.excluded) {
      std::printf("  legs' test: leg %zu -> %zu F %.2f > %.2f:", k, k + 1, v.first_f_statistic,
                  v.f_threshold);
      for (int i : v.dropped) {
        const TiePoint& t = leg_ties[k][static_cast<size_t>(i)];
        std::printf(" dropped %s (%s)", t.id.c_str(), right(k, t) ? "right" : "wrong");
      }
      std::printf("%s\n", v.excluded ? " and excluded the leg" : "");
    }
    if (leg_ties[k].empty() || v.excluded) continue;
    ++legs_kept;
    for (size_t i = 0; i < leg_ties[k].size(); ++i) {
      if (std::find(v.dropped.begin(), v.dropped.end(), static_cast<int>(i)) != v.dropped.end()) {
        continue;
      }
      ++kept;
      kept_right += right(k, leg_ties[k][i]) ? 1 : 0;
      kept_seen_right += truth(k, leg_ties[k][i]).sight ? 1 : 0;
    }
  }
  const auto percent = [&](int n) { return kept > 0 ? 100.0 * n / kept : 100.0; };
  std::printf(
      "after the legs' test: legs accepted %d; accepted tie points %d, %d right (%.1f %%); by "
      "the sight ray %d right (%.1f %%)\n",
      legs_kept, kept, kept_right, percent(kept_right), kept_seen_right, percent(kept_seen_right));
}

// How far apart the two sites' measured heights of a match lie, relative to their mean: the
// quantiles over the matches right by the sight ray, and each wrong one.
void PrintHeightDifferences(std::vector<double> right, std::vector<double> wrong) {
  std::sort(right.begin(), right.end());
  std::sort(wrong.begin(), wrong.end());
  const auto quantile = [&](double q) {
    return right.empty() ? std::nan("")
                         : right[static_cast<size_t>(q * static_cast<double>(right.size() - 1))];
  };
  std::printf(
      "relative height difference of the matches right by the sight ray (%zu): median %.2f, "
      "90 %% %.2f, 99 %% %.2f, max %.2f; wrong (%zu):",
      right.size(), quantile(0.5), quantile(0.9), quantile(0.99), quantile(1.0), wrong.size());
  for (double d : wrong) std::printf(" %.2f", d);
  std::printf("\n");
}

// How well the pair cost tells an eligible rock's true partner from the eligible peaks of site b
// within kLookAlikeDistance of it on other truth rocks (by the sight ray): how many of each pass
// max_model_cost, compared by the measured heights and by eq. 3.28 of the models, over all pairs
// and over those whose models both rest on min_shape_points or more.
constexpr double kLookAlikeDistance = 1.5;  // [m]
class CostDiscrimination {
 public:
  explicit CostDiscrimination(const RockMatchingOptions& options)
      : options_(options), heights_(options), models_(options) {
    heights_.compare_models = false;
    models_.compare_models = true;
    models_.min_shape_points = 0;
  }
  void Add(const ExtractedRock& p, const ExtractedRock& q, bool partner) {
    const bool determined = ModelsRestOnShapePoints(p, q, options_);
    const int by_heights = PairCost(p, q, heights_) <= options_.max_model_cost ? 1 : 0;
    const int by_models = PairCost(p, q, models_) <= options_.max_model_cost ? 1 : 0;
    for (int subset = 0; subset < (determined ? 2 : 1); ++subset) {
      std::array<int, 3>& c = counts_[partner ? 0 : 1][subset];
      ++c[0];
      c[1] += by_heights;
      c[2] += by_models;
    }
  }
  void Print() const {
    const auto percent = [](int n, int of) { return of > 0 ? 100.0 * n / of : std::nan(""); };
    for (int subset = 0; subset < 2; ++subset) {
      const std::array<int, 3>& t = counts_[0][subset];
      const std::array<int, 3>& l = counts_[1][subset];
      std::printf(
          "pair cost <= %.2f, %s: true partners %d, by the measured heights %.1f %%, by the "
          "models (eq. 3.28) %.1f %%; look-alikes within %.1f m %d, %.1f %% / %.1f %%\n",
          options_.max_model_cost,
          subset == 0 ? "all eligible pairs" : "both models from min_shape_points up", t[0],
          percent(t[1], t[0]), percent(t[2], t[0]), kLookAlikeDistance, l[0], percent(l[1], l[0]),
          percent(l[2], l[0]));
    }
  }

 private:
  const RockMatchingOptions options_;
  RockMatchingOptions heights_, models_;  // The options with each cost.
  // [true partner, look-alike][all, both models from min_shape_points]: pairs, passing by the
  // heights, passing by the models.
  std::array<std::array<std::array<int, 3>, 2>, 2> counts_{};
};

// One pass over the legs; returns the legs' conformal fits pooled at the a-priori covariances.
PooledVarianceFactor FunnelPass(const fs::path& mission_dir, const fs::path& run_dir,
                                const fs::path& rocks_csv, const MissionRunOptions& options,
                                const TruthPrior& truth_prior, LoadedSites* loaded) {
  std::ofstream rows;
  if (!rocks_csv.empty()) {
    rows.open(rocks_csv);
    if (!rows) throw Error(rocks_csv.string() + ": cannot write");
    rows << "leg,site,truth_id,truth_height_m,truth_radius_m,range_m,other_range_m,points,"
            "nearest_peak_m,nearest_height_m,nearest_on_rock,nearest_rule,stage,peak_dz_m,foot_dz_"
            "m,peak_along_m,peak_across_m\n";
  }
  const MissionManifest mission = ReadMissionManifest(mission_dir);
  const std::vector<Rigid3d> world_from_site = bench::TrueWorldFromSites(mission);
  const std::vector<TruthRock> truth = bench::ReadTruthRocks(*mission.truth_rocks_csv);
  std::map<int, const TruthRock*> by_id;
  for (const TruthRock& r : truth) by_id[r.id] = &r;
  const FaultDetectionOptions& fd = options.matching.fault_detection;
  std::printf("rocks >= %.2f m high, cameras <= %.0f m; rules counted at the first failure\n",
              fd.min_peak_to_plane_m, fd.max_peak_range_m);
  std::printf(
      "leg       dist  overlap ratio seen peaks | low few impl ratio sigma | elig matched "
      "wrong accepted  outcome\n");
  Funnel total, short_legs;
  int legs_accepted = 0, short_count = 0, short_accepted = 0;
  std::vector<SitePairError> fits;  // The legs' conformal fits, chi2 at tie_variance_factor 1.
  // For the legs' test after the loop: each accepted leg's tie points, and whether the match
  // behind each (by the rock id of site a) joins one truth rock.
  const size_t leg_count = mission.sites.size() - 1;
  std::vector<std::vector<TiePoint>> leg_ties(leg_count);
  std::vector<std::map<int, MatchTruth>> truth_by_rock_a(leg_count);
  const bench::SightRayTruth sight_rays(truth, mission.origin.h);
  // Every match's relative height difference |H_a - H_b| / mean, by the sight ray's verdict.
  std::vector<double> height_difference_right, height_difference_wrong;
  CostDiscrimination costs(options.matching);
  loaded->sites.resize(mission.sites.size());
  const auto site_at = [&](size_t k) -> const Site& {
    if (!loaded->sites[k]) {
      loaded->sites[k] = LoadSite(run_dir, mission.sites[k].site, world_from_site[k], truth,
                                  sight_rays, options, &loaded->agreement);
    }
    return *loaded->sites[k];
  };
  for (size_t k = 0; k + 1 < mission.sites.size(); ++k) {
    const Site& a = site_at(k);
    const Site& b = site_at(k + 1);
    const Rigid3d site_a_from_world = world_from_site[k].Inverse();
    const Rigid3d site_b_from_world = world_from_site[k + 1].Inverse();
    const Eigen::Vector3d cam_a_in_a = site_a_from_world * a.camera_world;
    const Eigen::Vector3d cam_b_in_a = site_a_from_world * b.camera_world;
    const Eigen::Vector3d cam_a_in_b = site_b_from_world * a.camera_world;
    const Eigen::Vector3d cam_b_in_b = site_b_from_world * b.camera_world;
    char name[64];
    std::snprintf(name, sizeof(name), "legs/leg_%03d_%03d", mission.sites[k].site,
                  mission.sites[k + 1].site);
    const fs::path leg = run_dir / name;
    std::ifstream unit_file(leg / "unit.json"), matches_file(leg / "matches.csv");
    if (!unit_file || !matches_file) throw Error(leg.string() + ": no unit.json or matches.csv");
    const nlohmann::json summary = nlohmann::json::parse(unit_file)["summary"];
    std::string outcome = summary.value("outcome", std::string("?"));
    std::set<std::pair<int, int>> matched_pairs;  // Extracted rock indices (a, b).
    std::map<int, RockMatchOutcome> outcome_of;   // Rock of a -> what became of it.
    Funnel f;
    std::optional<RockMatchingPrior> prior =
        RecordedPrior(summary.value("prior", nlohmann::json::object()));
    if (prior && truth_prior.position_sigma_m >= 0.0) {
      prior->a_from_b = site_a_from_world * world_from_site[k + 1];
      prior->position_sigma_m = truth_prior.position_sigma_m;
      prior->heading_sigma_deg = truth_prior.heading_sigma_deg;
      prior->source = "truth (bench)";
    }
    if (prior) {
      SiteRocks rocks_a, rocks_b;
      rocks_a.site = mission.sites[k].site;
      rocks_a.camera_center = cam_a_in_a;
      rocks_a.rocks = a.rocks;
      rocks_b.site = mission.sites[k + 1].site;
      rocks_b.camera_center = cam_b_in_b;
      rocks_b.rocks = b.rocks;
      const SitePairMatch match = MatchSitePair(rocks_a, rocks_b, *prior, options.matching);
      outcome = ToString(match.report.outcome);
      // The pair-level rules that excluded the leg, with their values (e.g. RE 2.4 %).
      for (const FaultCheck& check : match.report.checks) {
        if (!check.ExcludesPair()) continue;
        char because[160];
        std::snprintf(because, sizeof(because), "; %s %.3g", check.rule.c_str(), check.value);
        outcome += because;
      }
      leg_ties[k] = match.tie_points;
      for (const RockMatch& m : match.matches) matched_pairs.insert({m.rock_a, m.rock_b});
      for (const RockMatchOutcome& o : match.outcomes) outcome_of[o.rock_a] = o;
      f.leg_matches = static_cast<int>(match.matches.size());
      if (match.error) {
        fits.push_back(*match.error);
        fits.back().chi2 *= options.matching.tie_variance_factor;
      }
    } else {
      if (outcome == "matched") leg_ties[k] = ReadTiePoints(leg / "tie_points.json");
      std::string line;
      std::getline(matches_file, line);
      while (std::getline(matches_file, line)) {
        const std::vector<std::string> fields = SplitCsvLine(line);
        const int ia = a.id_to_index.at(std::stoi(fields[0]));
        const int ib = b.id_to_index.at(std::stoi(fields[1]));
        matched_pairs.insert({ia, ib});
        ++f.leg_matches;
      }
    }
    const bool accepted = outcome == "matched";
    int correct_matches = 0;
    const double distance = (b.camera_world - a.camera_world).head<2>().norm();
    for (const TruthRock& r : truth) {
      if (r.height < fd.min_peak_to_plane_m) continue;
      const Eigen::Vector3d top(r.north_east.x(), r.north_east.y(), a.camera_world.z() + 1.0);
      if ((r.north_east - a.camera_world.head<2>()).norm() > fd.max_peak_range_m ||
          (r.north_east - b.camera_world.head<2>()).norm() > fd.max_peak_range_m) {
        continue;
      }
      ++f.overlap;
      if (DistanceRatio(top, a.camera_world, b.camera_world) < fd.min_rock_distance_ratio) continue;
      ++f.ratio;
      const auto points_on = [&](const Site& s) {
        const auto found = s.points_on_rock.find(r.id);
        return found == s.points_on_rock.end() ? 0 : found->second;
      };
      if (points_on(a) < 5 || points_on(b) < 5) continue;
      ++f.seen;
      if (rows.is_open()) {
        for (int side = 0; side < 2; ++side) {
          const Site& s = side == 0 ? a : b;
          const Site& o = side == 0 ? b : a;
          int nearest = -1;
          double best = 1e9;
          for (size_t q = 0; q < s.peaks_world.size(); ++q) {
            const double d = (s.peaks_world[q] - r.north_east).norm();
            if (d < best) {
              best = d;
              nearest = static_cast<int>(q);
            }
          }
          const bool on =
              s.rocks_on.count(r.id) &&
              std::count(s.rocks_on.at(r.id).begin(), s.rocks_on.at(r.id).end(), nearest) > 0;
          const Eigen::Vector3d own = side == 0 ? cam_a_in_a : cam_b_in_b;
          const Eigen::Vector3d other = side == 0 ? cam_b_in_a : cam_a_in_b;
          char row[512];
          std::snprintf(
              row, sizeof(row), "%zu,%d,%d,%.3f,%.3f,%.2f,%.2f,%d,%.3f,%.3f,%d,%s,", k, side, r.id,
              r.height, r.radius, (r.north_east - s.camera_world.head<2>()).norm(),
              (r.north_east - o.camera_world.head<2>()).norm(), s.points_on_rock.at(r.id), best,
              nearest >= 0 ? s.rocks[nearest].height_m : 0.0, on ? 1 : 0,
              nearest >= 0
                  ? ToString(CheckRockRules(s.rocks[nearest], own, other, options.matching)).c_str()
                  : "none");
          // Elevation errors of the peak (against the true top) and of its foot on the fitted
          // plane (against the true ground) [m], up positive.
          const double h0 = mission.origin.h;
          rows << row << (a.rocks_on.count(r.id) && b.rocks_on.count(r.id) ? "peaks" : "seen")
               << "," << (nearest >= 0 ? h0 - s.peak_z_world[nearest] - r.ground_z - r.height : 0.0)
               << "," << (nearest >= 0 ? h0 - s.foot_z_world[nearest] - r.ground_z : 0.0);
          // Horizontal offset of the peak from the truth rock's centre along the line of sight
          // (away from the camera positive) and across it [m].
          const Eigen::Vector2d sight = (r.north_east - s.camera_world.head<2>()).normalized();
          const Eigen::Vector2d offset =
              nearest >= 0 ? Eigen::Vector2d(s.peaks_world[nearest] - r.north_east)
                           : Eigen::Vector2d::Zero();
          rows << "," << offset.dot(sight) << ","
               << offset.dot(Eigen::Vector2d(-sight.y(), sight.x())) << "\n";
        }
      }
      if (!a.rocks_on.count(r.id) || !b.rocks_on.count(r.id)) continue;
      ++f.peaks;
      int ka = -1, kb = -1;
      const RockRule rule_a = BestRule(a, r.id, cam_a_in_a, cam_b_in_a, options.matching, &ka);
      const RockRule rule_b = BestRule(b, r.id, cam_b_in_b, cam_a_in_b, options.matching, &kb);
      if (rule_a != RockRule::kEligible || rule_b != RockRule::kEligible) {
        const int ra = rule_a == RockRule::kEligible ? kRules : static_cast<int>(rule_a);
        const int rb = rule_b == RockRule::kEligible ? kRules : static_cast<int>(rule_b);
        ++f.failed[std::min(ra, rb)];
        continue;
      }
      ++f.eligible;
      // The pair costs of the true partners and of site b's eligible look-alikes near the partner.
      costs.Add(a.rocks[ka], b.rocks[kb], true);
      for (size_t q = 0; q < b.peaks_world.size(); ++q) {
        const double d = (b.peaks_world[q] - b.peaks_world[kb]).norm();
        if (static_cast<int>(q) == kb || d > kLookAlikeDistance || b.seen_on[q] == r.id ||
            CheckRockRules(b.rocks[q], cam_b_in_b, cam_a_in_b, options.matching) !=
                RockRule::kEligible) {
          continue;
        }
        costs.Add(a.rocks[ka], b.rocks[q], false);
      }
      bool joined = false;
      for (int ia : a.rocks_on.at(r.id)) {
        for (int ib : b.rocks_on.at(r.id)) joined = joined || matched_pairs.count({ia, ib}) > 0;
      }
      if (!joined) {
        const auto it = outcome_of.find(ka);
        const std::string fate =
            it == outcome_of.end() ? "outside the prior's overlap" : it->second.fate;
        ++f.lost_in_matching[fate];
        const std::vector<int>& partners = b.rocks_on.at(r.id);
        if (it != outcome_of.end() &&
            std::find(partners.begin(), partners.end(), it->second.rock_b) != partners.end()) {
          ++f.lost_with_true_candidate[fate];
        }
        continue;
      }
      ++f.matched;
      f.accepted += accepted ? 1 : 0;
    }
    // Wrong matches: the two peaks are not on one truth rock (any height).
    for (const auto& [ia, ib] : matched_pairs) {
      const auto on = [&](const Site& s, int index) {
        for (const auto& [id, list] : s.rocks_on) {
          if (std::find(list.begin(), list.end(), index) != list.end()) return id;
        }
        return -1;
      };
      const int ta = on(a, ia), tb = on(b, ib);
      const int sa = a.seen_on[ia], sb = b.seen_on[ib];
      const MatchTruth verdict{ta >= 0 && ta == tb, sa >= 0 && sa == sb};
      truth_by_rock_a[k][a.rocks[ia].id] = verdict;
      // The covariance rule's verdict: wrong only where no truth rock could have made both peaks.
      const std::vector<int>& ca = a.could_make[ia];
      const std::vector<int>& cb = b.could_make[ib];
      const bool shared = std::any_of(ca.begin(), ca.end(), [&](int id) {
        return std::find(cb.begin(), cb.end(), id) != cb.end();
      });
      if (!shared) {
        ++f.no_common_rock;
        f.no_common_rock_accepted += accepted ? 1 : 0;
      }
      int decoy = -1;
      double decoy_distance = 1.5;
      for (size_t q = 0; q < b.peaks_world.size(); ++q) {
        const double d = (b.peaks_world[q] - b.peaks_world[ib]).norm();
        if (static_cast<int>(q) != ib && d < decoy_distance) {
          decoy_distance = d;
          decoy = static_cast<int>(q);
        }
      }
      if (decoy >= 0) {
        ++f.decoys;
        const int td = on(b, decoy);
        f.decoys_right_by_disk += ta >= 0 && ta == td ? 1 : 0;
        f.decoys_right_by_sight += sa >= 0 && sa == b.seen_on[decoy] ? 1 : 0;
      }
      const double mean_height = 0.5 * (a.rocks[ia].height_m + b.rocks[ib].height_m);
      (verdict.sight ? height_difference_right : height_difference_wrong)
          .push_back(std::abs(a.rocks[ia].height_m - b.rocks[ib].height_m) / mean_height);
      if (!verdict.sight) {
        ++f.wrong_by_sight;
        f.wrong_by_sight_accepted += accepted ? 1 : 0;
      }
      if (verdict.disk) {
        ++correct_matches;
      } else {
        ++f.wrong_matches;
        f.wrong_accepted += accepted ? 1 : 0;
      }
      if (!verdict.disk || !verdict.sight) {
        const ExtractedRock& ra = a.rocks[ia];
        const ExtractedRock& rb = b.rocks[ib];
        const double apart = (a.peaks_world[ia] - b.peaks_world[ib]).norm();
        std::printf(
            "  wrong match%s: rocks %d / %d on truth %d / %d, sight ray %d / %d, peaks %.2f m "
            "apart (true frames), ranges %.1f / %.1f m, heights %.2f / %.2f m, sigma %.2f / %.2f "
            "m%s%s\n",
            accepted ? " (accepted)" : "", ra.id, rb.id, ta, tb, sa, sb, apart, ra.range_m,
            rb.range_m, ra.height_m, rb.height_m,
            std::sqrt(ra.peak_covariance.topLeftCorner<2, 2>().trace()),
            std::sqrt(rb.peak_covariance.topLeftCorner<2, 2>().trace()),
            shared ? "; one truth rock could have made both peaks (covariance rule)" : "",
            verdict.disk    ? "; right by the disk rule"
            : verdict.sight ? "; right by the sight ray"
                            : "");
      }
    }
    (void)correct_matches;
    std::printf(
        "%2zu -> %2zu %5.1f  %7d %5d %4d %5d | %3d %3d %4d %5d %5d | %4d %7d %5d %8d  %s%s\n", k,
        k + 1, distance, f.overlap, f.ratio, f.seen, f.peaks,
        f.failed[static_cast<int>(RockRule::kTooLow)],
        f.failed[static_cast<int>(RockRule::kFewPoints)],
        f.failed[static_cast<int>(RockRule::kImplausible)],
        f.failed[static_cast<int>(RockRule::kLowRatio)],
        f.failed[static_cast<int>(RockRule::kImprecise)], f.eligible, f.matched, f.wrong_matches,
        f.accepted, outcome.c_str(), f.leg_matches > 0 && accepted ? "" : "");
    if (!accepted && !f.lost_in_matching.empty()) {
      std::printf("           lost (true candidate):");
      for (const auto& [fate, n] : f.lost_in_matching) {
        const auto t = f.lost_with_true_candidate.find(fate);
        std::printf(" %s %d (%d);", fate.c_str(), n,
                    t == f.lost_with_true_candidate.end() ? 0 : t->second);
      }
      std::printf("\n");
    }
    const auto add = [](Funnel* t, const Funnel& x) {
      t->overlap += x.overlap;
      t->ratio += x.ratio;
      t->seen += x.seen;
      t->peaks += x.peaks;
      t->eligible += x.eligible;
      t->matched += x.matched;
      t->accepted += x.accepted;
      t->wrong_matches += x.wrong_matches;
      t->wrong_accepted += x.wrong_accepted;
      t->wrong_by_sight += x.wrong_by_sight;
      t->wrong_by_sight_accepted += x.wrong_by_sight_accepted;
      t->decoys += x.decoys;
      t->decoys_right_by_disk += x.decoys_right_by_disk;
      t->decoys_right_by_sight += x.decoys_right_by_sight;
      t->no_common_rock += x.no_common_rock;
      t->no_common_rock_accepted += x.no_common_rock_accepted;
      t->leg_matches += x.leg_matches;
      for (int i = 0; i < kRules; ++i) t->failed[i] += x.failed[i];
      for (const auto& [fate, n] : x.lost_in_matching) t->lost_in_matching[fate] += n;
      for (const auto& [fate, n] : x.lost_with_true_candidate) {
        t->lost_with_true_candidate[fate] += n;
      }
    };
    add(&total, f);
    legs_accepted += accepted ? 1 : 0;
    if (distance <= 25.0) {
      add(&short_legs, f);
      ++short_count;
      short_accepted += accepted ? 1 : 0;
    }
  }
  const auto print = [](const char* label, const Funnel& f) {
    std::printf(
        "%s: overlap %d, ratio %d, seen %d, peaks %d; failing: too low %d, few points %d, "
        "implausible %d, ratio %d, peak sigma %d; eligible %d, matched %d, accepted %d; "
        "wrong matches %d (accepted %d) of %d; no truth rock could have made both peaks: %d "
        "(accepted %d); wrong by the sight ray %d (accepted %d)\n",
        label, f.overlap, f.ratio, f.seen, f.peaks, f.failed[static_cast<int>(RockRule::kTooLow)],
        f.failed[static_cast<int>(RockRule::kFewPoints)],
        f.failed[static_cast<int>(RockRule::kImplausible)],
        f.failed[static_cast<int>(RockRule::kLowRatio)],
        f.failed[static_cast<int>(RockRule::kImprecise)], f.eligible, f.matched, f.accepted,
        f.wrong_matches, f.wrong_accepted, f.leg_matches, f.no_common_rock,
        f.no_common_rock_accepted, f.wrong_by_sight, f.wrong_by_sight_accepted);
    std::printf(
        "  decoys (site b's peak nearest to the match's, within 1.5 m) %d: called right by the "
        "disk rule %d, by the sight ray %d\n",
        f.decoys, f.decoys_right_by_disk, f.decoys_right_by_sight);
    std::printf("  eligible at both but not matched:");
    for (const auto& [fate, n] : f.lost_in_matching) std::printf(" %s %d;", fate.c_str(), n);
    std::printf("\n  ... of which the judged candidate was the true partner:");
    for (const auto& [fate, n] : f.lost_with_true_candidate) {
      std::printf(" %s %d;", fate.c_str(), n);
    }
    std::printf("\n");
  };
  print("all legs", total);
  print("legs <= 25 m", short_legs);
  std::printf("legs accepted: %d of %zu; legs <= 25 m accepted: %d of %d\n", legs_accepted,
              mission.sites.size() - 1, short_accepted, short_count);
  std::printf(
      "peaks on the same truth rock (or none) by the disk rule and the sight ray: %d of %d with "
      "sigma < 0.1 m, %d of %d with more\n",
      loaded->agreement.agree[0], loaded->agreement.peaks[0], loaded->agreement.agree[1],
      loaded->agreement.peaks[1]);
  PrintHeightDifferences(height_difference_right, height_difference_wrong);
  costs.Print();
  if (options.leg_test) PrintLegTest(leg_ties, truth_by_rock_a, options.LegTestOptions());
  const PooledVarianceFactor pooled = PoolVarianceFactor(fits);
  std::printf(
      "conformal fits of %d legs: chi2 %.1f at tie_variance_factor 1, redundancy %d, pooled "
      "sigma0^2 %.3f (95 %% upper bound %.3f)\n",
      pooled.fits, pooled.chi2, pooled.redundancy, pooled.estimate, pooled.upper_95);
  return pooled;
}

// The funnel as `areomap run` gathers its legs: the first pass, then, when the run would make
// one (MissionRunOptions::RockVariancePassFactor), the second at the first pass's factor.
int Main(const fs::path& mission_dir, const fs::path& run_dir, const fs::path& rocks_csv,
         MissionRunOptions options, const TruthPrior& truth_prior) {
  LoadedSites loaded;
  const PooledVarianceFactor first_pass =
      FunnelPass(mission_dir, run_dir, rocks_csv, options, truth_prior, &loaded);
  const std::optional<double> factor = options.RockVariancePassFactor(first_pass);
  if (!factor) {
    std::printf("no second pass (off, or pooled redundancy %d < %d)\n", first_pass.redundancy,
                options.rock_variance_pass_min_redundancy);
    return 0;
  }
  std::printf("\nsecond pass: the legs matched again at tie_variance_factor %.3f\n", *factor);
  options.matching.tie_variance_factor = *factor;
  FunnelPass(mission_dir, run_dir, "", options, truth_prior, &loaded);
  return 0;
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s MISSION_DIR RUN_DIR [ROCKS_CSV] [NAME=VALUE...]\n", argv[0]);
    return 2;
  }
  try {
    areomap::MissionRunOptions options;
    areomap::TruthPrior truth_prior;
    std::string rocks_csv;
    for (int i = 3; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg.find('=') == std::string::npos) {
        rocks_csv = arg;
      } else {
        areomap::ApplyOverride(arg, &options, &truth_prior);
      }
    }
    return areomap::Main(argv[1], argv[2], rocks_csv, options, truth_prior);
  } catch (const areomap::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
