#include "areomap/pipeline/mission_run.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <functional>
#include <mutex>
#include <numbers>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/adjustment/traverse_adjustment.h"
#include "areomap/landmarks/localization_error.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/output_folder.h"
#include "areomap/pipeline/run_report.h"
#include "areomap/pipeline/work_plan.h"
#include "mission_units.h"

namespace areomap {
namespace mission_run {

namespace fs = std::filesystem;
using nlohmann::json;

json ReadJsonOrNull(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return nullptr;
  json parsed = json::parse(in, nullptr, false);
  return parsed.is_discarded() ? json(nullptr) : parsed;
}

MissionRunContext::MissionRunContext(const MissionManifest& mission_in,
                                     const MissionRunOptions& options_in, fs::path out_dir_in)
    : mission(&mission_in),
      options(&options_in),
      out_dir(std::move(out_dir_in)),
      map(MapFrame::LocalEquirectangular(mission_in.body, mission_in.origin)) {}

RunContext::RunContext(const MissionManifest& mission_in, const MissionRunOptions& options_in,
                       fs::path out_dir_in)
    : MissionRunContext(mission_in, options_in, std::move(out_dir_in)),
      fingerprint(json{{"mission", fs::absolute(mission_in.root).lexically_normal().string()},
                       {"inputs", FilesIdentity(mission_in.files, mission_in.root)},
                       {"options", options_in.ToJson()}}
                      .dump()) {}

OutputFolderOptions RunFolderPolicy(const fs::path& mission, bool overwrite) {
  OutputFolderOptions policy;
  policy.command = "run";
  // The plan's claims and done records (.areomap-units/) are areomap's own dot files.
  policy.outputs = {"sites/",    "legs/",     "guided/",     "adjustment/",
                    "craters/",  "products/", "report.html", "summary.json",
                    "plan.json", "error.txt", "slurm/",      "parallel/"};
  policy.inputs = {mission};
  policy.overwrite = overwrite;
  policy.in_place = true;
  return policy;
}

fs::path SiteDir(const MissionRunContext& run, int site) {
  return run.out_dir / "sites" / SiteUnitId(site);
}

fs::path LegDir(const MissionRunContext& run, int site_a, int site_b) {
  return run.out_dir / "legs" / LegUnitId(site_a, site_b);
}

namespace {

// The unit's products: the names of the regular files in its folder, sorted, but unit.json and
// hidden files (AtomicFile's temporaries).
std::vector<std::string> UnitOutputFiles(const fs::path& unit_dir) {
  std::vector<std::string> names;
  for (const fs::directory_entry& entry : fs::directory_iterator(unit_dir)) {
    const std::string name = entry.path().filename().string();
    if (entry.is_regular_file() && name != "unit.json" && !name.starts_with('.')) {
      names.push_back(name);
    }
  }
  std::sort(names.begin(), names.end());
  return names;
}

// Whether every file unit.json lists ("files") is still in the unit's folder.
bool UnitOutputFilesExist(const json& unit, const fs::path& unit_dir) {
  const json files = unit.value("files", json());
  if (!files.is_array()) return false;
  for (const json& name : files) {
    if (!name.is_string() || !fs::is_regular_file(unit_dir / name.get<std::string>())) {
      return false;
    }
  }
  return true;
}

}  // namespace

json FinishedUnit(const RunContext& run, const fs::path& unit_dir) {
  const json unit = ReadJsonOrNull(unit_dir / "unit.json");
  if (!unit.is_object() || unit.value("fingerprint", "") != run.fingerprint ||
      !UnitOutputFilesExist(unit, unit_dir)) {
    return nullptr;
  }
  return unit.value("summary", json(nullptr));
}

void FinishUnit(const RunContext& run, const fs::path& unit_dir, const json& summary) {
  WriteFileAtomically(unit_dir / "unit.json", json{{"fingerprint", run.fingerprint},
                                                   {"files", UnitOutputFiles(unit_dir)},
                                                   {"summary", summary}}
                                                  .dump(2));
}

Rigid3d TelemetryTraverseFromSite(const MissionSitePose& pose) {
  // Site frames are level and north-up as the rover believes: a pure translation.
  return Rigid3d(Eigen::Quaterniond::Identity(), pose.position);
}

double DrivenDistance(const MissionManifest& mission, size_t site_index) {
  double distance = 0.0;
  for (size_t i = 1; i <= site_index && i < mission.telemetry.size(); ++i) {
    distance +=
        (mission.telemetry[i].position - mission.telemetry[i - 1].position).head<2>().norm();
  }
  return distance;
}

namespace {

// network.json in the adjustment format (docs/adjustment-format.md): the sites at their
// telemetry poses, a dead-reckoning prior per leg and, when the mission has it, the truth.
json NetworkJson(const MissionManifest& mission, const MissionRunOptions& options) {
  BundleInput network;
  network.body = mission.body;
  network.origin = mission.origin;
  network.site_count = static_cast<int>(mission.sites.size());
  const double heading_sigma = options.leg_heading_sigma_deg * std::numbers::pi / 180.0;
  Vector6d floor;
  floor << 1e-3, 1e-3, 1e-3, 0.02, 0.02, 0.02;
  for (size_t i = 0; i < mission.sites.size(); ++i) {
    network.initial_poses.push_back(TelemetryTraverseFromSite(mission.telemetry[i]));
    if (i == 0) continue;
    RelativePosePrior prior;
    prior.site_a = static_cast<int>(i - 1);
    prior.site_b = static_cast<int>(i);
    prior.a_from_b = network.initial_poses[i - 1].Inverse() * network.initial_poses[i];
    prior.covariance = DeadReckoningCovariance(prior.a_from_b.translation, options.leg_scale_sigma,
                                               heading_sigma, floor);
    network.priors.push_back(prior);
  }
  std::vector<Eigen::Vector3d> truth;
  for (const MissionSitePose& pose : mission.truth_sites) truth.push_back(pose.position);
  if (truth.size() != mission.sites.size()) truth.clear();
  return BundleInputToJson(network, truth);
}

// The adjusted site poses (traverse_from_site) from adjustment.json (BundleResult's JSON).
std::vector<Rigid3d> AdjustedPoses(const fs::path& adjustment_json, size_t site_count) {
  const json result = ReadJsonOrNull(adjustment_json);
  const json sites = result.is_object() ? result.value("sites", json()) : json();
  if (!sites.is_array() || sites.size() != site_count) {
    throw Error(adjustment_json.string() + ": expected \"sites\" with " +
                std::to_string(site_count) + " adjusted poses");
  }
  std::vector<Rigid3d> poses;
  for (const json& site : sites) {
    try {
      const auto p = site.at("adjusted").at("position_m").get<std::vector<double>>();
      const auto q = site.at("adjusted").at("rotation_wxyz").get<std::vector<double>>();
      if (p.size() != 3 || q.size() != 4) throw Error("");
      poses.emplace_back(Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized(),
                         Eigen::Vector3d(p[0], p[1], p[2]));
    } catch (const std::exception&) {
      throw Error(adjustment_json.string() + ": sites[" + std::to_string(poses.size()) +
                  "].adjusted: expected position_m [3] and rotation_wxyz [4]");
    }
  }
  return poses;
}

}  // namespace
}  // namespace mission_run

std::optional<double> MissionRunOptions::RockVariancePassFactor(
    const PooledVarianceFactor& first_pass) const {
  if (!rock_variance_pass || first_pass.redundancy < rock_variance_pass_min_redundancy ||
      !std::isfinite(first_pass.upper_95) || first_pass.upper_95 <= 0.0) {
    return std::nullopt;
  }
  return first_pass.upper_95;
}

void MissionRunOptions::Check() const {
  stereo.Check();
  dtm.Check();
  ortho.Check();
  match.Check();
  control.Check();
  rocks.Check();
  matching.Check();
  bundle.Check();
  RequireOption(point_spacing_m > 0.0, "MissionRunOptions.point_spacing_m",
                "a positive ground spacing in metres");
  RequireOption(fine_pair_point_spacing_m > 0.0, "MissionRunOptions.fine_pair_point_spacing_m",
                "a positive ground spacing in metres");
  RequireOption(fine_pair_max_ifov_mrad >= 0.0, "MissionRunOptions.fine_pair_max_ifov_mrad",
                "a non-negative angular resolution in mrad per pixel (0: no pair is fine)");
  precise_pairs.Check();
  RequireOption(prior_sigma_floor_m > 0.0, "MissionRunOptions.prior_sigma_floor_m",
                "a positive sigma in metres");
  RequireOption(prior_sigma_per_m >= 0.0 && prior_sigma_per_m <= 1.0,
                "MissionRunOptions.prior_sigma_per_m",
                "a fraction of the distance driven in [0, 1]");
  CheckModelsCoverHeightRule(rocks, matching);
  RequireOption(leg_scale_sigma > 0.0, "MissionRunOptions.leg_scale_sigma",
                "a positive relative leg-length sigma");
  craters.Check();
  mosaic.Check();
  RequireOption(crater_min_diameter_m > 0.0, "MissionRunOptions.crater_min_diameter_m",
                "a positive rim diameter in metres");
  RequireOption(traverse_posting_m > 0.0, "MissionRunOptions.traverse_posting_m",
                "a positive posting in metres");
  RequireOption(leg_heading_sigma_deg > 0.0, "MissionRunOptions.leg_heading_sigma_deg",
                "a positive heading drift sigma in degrees");
  RequireOption(leg_test_alpha > 0.0 && leg_test_alpha < 1.0, "MissionRunOptions.leg_test_alpha",
                "a false alarm rate in (0, 1)");
  RequireOption(rock_variance_pass_min_redundancy >= 1,
                "MissionRunOptions.rock_variance_pass_min_redundancy", ">= 1");
  RequireOption(guided_passes >= 0, "MissionRunOptions.guided_passes", ">= 0");
  RequireOption(guided_sigma_floor_m > 0.0, "MissionRunOptions.guided_sigma_floor_m",
                "a positive sigma in metres");
  RequireOption(guided_null_windows >= 8, "MissionRunOptions.guided_null_windows",
                ">= 8 windows for a chance level");
}

LegConsistencyOptions MissionRunOptions::LegTestOptions() const {
  LegConsistencyOptions test;
  test.alpha = leg_test_alpha;
  test.max_residual_chi2 = matching.max_residual_chi2;
  test.min_tie_points = matching.fault_detection.min_tie_points;
  return test;
}

nlohmann::json MissionRunOptions::ToJson() const {
  // The figures a user changes from the CLI; the fingerprint only needs to change with them.
  nlohmann::json figures = {
      {"stereo_max_range_m", stereo.max_range_m},
      {"point_spacing_m", point_spacing_m},
      {"fine_pair_point_spacing_m", fine_pair_point_spacing_m},
      {"fine_pair_max_ifov_mrad", fine_pair_max_ifov_mrad},
      {"precise_pair_ratio", prefer_precise_pairs ? precise_pairs.sigma_ratio : 0.0},
      {"precise_pair_cell_m", precise_pairs.cell_m},
      {"stereo_block_size", stereo.block_size},
      {"dtm_posting_m", dtm.posting_m},
      {"dtm_method", ToString(dtm.gridding.method)},
      {"ortho_max_range_m", ortho.max_range_m},
      {"match_max_false_match", match.max_false_match},
      {"match_max_rotation_deg", match.max_rotation_deg},
      {"match_subpixel_floor_px", match.subpixel_floor_px},
      // Not on the CLI, but they set the sites' rotation sigmas; runs made before the floor grew
      // at low correlation (2026-12-04) lack them and are recomputed rather than reused.
      {"match_rotation_floor_deg", match.rotation_floor_deg},
      {"match_rotation_floor_correlation", match.rotation_floor_correlation},
      {"control_spacing_m", control.spacing_m},
      {"control_site_sigma_m", control.site_sigma_m},
      {"prior_sigma_floor_m", prior_sigma_floor_m},
      {"prior_sigma_per_m", prior_sigma_per_m},
      {"rocks_min_height_m", rocks.min_height_m},
      // Not on the CLI, but they decide which legs' rocks are ambiguous; runs made before
      // similar low neighbours counted (2026-12-04) lack them and are recomputed, not reused.
      {"rock_ambiguity_similar_min_height_m", matching.ambiguity_similar_min_height_m},
      {"rock_ambiguity_similar_height_difference", matching.ambiguity_similar_height_difference},
      {"leg_scale_sigma", leg_scale_sigma},
      {"leg_heading_sigma_deg", leg_heading_sigma_deg},
      {"bundle_huber_scale", bundle.huber_scale},
      {"bundle_rejection_alpha", bundle.rejection_alpha},
      {"detect_craters", detect_craters},
      {"crater_min_diameter_m", crater_min_diameter_m},
      {"traverse_products", traverse_products},
      {"traverse_posting_m", traverse_posting_m},
      {"mosaic_feather_m", mosaic.feather_m}};
  // The height rule (run --rock-min-height) decides which rocks are modeled and eligible, the
  // low rocks' sigma limit which of them are matched; runs made before the rule became 12 cm
  // (2026-12-04) lack them and are recomputed rather than reused with 15 cm.
  figures["rocks_model_min_height_m"] = rocks.model_min_height_m;
  figures["rock_min_peak_to_plane_m"] = matching.fault_detection.min_peak_to_plane_m;
  figures["rock_low_rock_max_peak_sigma_m"] = matching.low_rock_max_peak_sigma_m;
  // Since 2026-12-05 the limit holds for pairs of two low rocks only (one before).
  figures["rock_low_pair_max_height_m"] = matching.low_pair_max_height_m;
  // Since 2026-12-05 the pattern vouches for pairs against the low-pair limit and the pair cost
  // (no exemption before).
  figures["rock_pattern_vouch_deviation_m"] = matching.pattern_vouch_deviation_m;
  figures["rock_pattern_vouch_votes"] = matching.pattern_vouch_votes;
  // Since 2026-12-05 (second change) a vouched pair's off-pattern alternatives are ruled out.
  figures["rock_pattern_vouch_rules_out_alternatives"] =
      matching.pattern_vouch_rules_out_alternatives;
  // Three significant rocks per cell since 2026-12-04 (one before): legs made with one are
  // recomputed.
  figures["rock_significant_per_cell"] = matching.significant_per_cell;
  // The pattern settles the methods' disagreements since 2026-12-04: legs matched before are
  // recomputed.
  figures["rock_pattern_settles_disagreement"] = matching.pattern_settles_disagreement;
  // Since 2026-12-04 (the consensus translation, models compared from min_shape_points up).
  figures["rock_consensus_translation"] = matching.consensus_translation;
  // Since 2026-12-05 the pattern's turn is fitted with its translation.
  figures["rock_consensus_turn"] = matching.consensus_turn;
  figures["rock_consensus_turn_trim_m"] = matching.consensus_turn_trim_m;
  figures["rock_min_shape_points"] = matching.min_shape_points;
  // Since 2026-12-05 pairs are compared by their measured heights (by their models before).
  figures["rock_compare_models"] = matching.compare_models;
  // Library callers may change the rock ties' variance factor: legs made with another are not
  // reused. Left out at its default, so that earlier runs keep their fingerprint.
  if (matching.tie_variance_factor != 1.0) {
    figures["rock_tie_variance_factor"] = matching.tie_variance_factor;
  }
  return figures;
}

namespace mission_run {
namespace {

// One progress bar for the whole run, shared by the site units running in parallel: sites 60 %,
// legs 15 % (the first pass 80 % of it), craters 3 %, the adjustment 5 %, products 17 %. A
// callback that answers false cancels the run.
class RunProgress {
 public:
  static constexpr double kSites = 0.6, kLegs = 0.75, kCraters = 0.78, kAdjustment = 0.83;
  static constexpr double kFirstPass = kSites + 0.8 * (kLegs - kSites);

  RunProgress(const ProgressCallback& progress, size_t site_count)
      : progress_(progress), site_done_(site_count, 0.0) {}

  bool Report(double fraction, std::string_view stage) {
    if (!progress_) return true;
    std::lock_guard lock(mutex_);
    const bool go = progress_(fraction, stage);
    if (!go) cancelled_ = true;
    return go;
  }
  ProgressCallback Span(double from, double to) {
    return [this, from, to](double f, std::string_view stage) {
      return Report(from + (to - from) * f, stage);
    };
  }
  // Site i's own fraction, shown as the sites' share done.
  ProgressCallback Site(size_t i) {
    return [this, i](double f, std::string_view stage) {
      double sum = 0.0;
      {
        std::lock_guard lock(mutex_);
        site_done_[i] = f;
        for (double d : site_done_) sum += d;
      }
      return Report(kSites * sum / static_cast<double>(site_done_.size()), stage);
    };
  }
  void SiteDone(size_t i) {
    std::lock_guard lock(mutex_);
    site_done_[i] = 1.0;
  }
  // Leg i of `count` within [from, to].
  ProgressCallback Leg(size_t i, size_t count, double from, double to) {
    return [this, i, count, from, to](double f, std::string_view stage) {
      const double n = static_cast<double>(count);
      return Report(from + (to - from) * (static_cast<double>(i) + f) / n, stage);
    };
  }
  bool cancelled() const { return cancelled_; }

 private:
  ProgressCallback progress_;
  std::mutex mutex_;
  std::vector<double> site_done_;
  std::atomic<bool> cancelled_ = false;
};

// Every site unit, in parallel (TBB), computed or reused; counts them in `summary`.
std::vector<SiteUnitResult> RunSiteStage(const RunContext& run, RunProgress& bar,
                                         MissionRunSummary& summary) {
  const size_t site_count = run.mission->sites.size();
  std::vector<SiteUnitResult> sites(site_count);
  std::vector<char> reused(site_count, 0);  // Not vector<bool>: written from parallel tasks.
  tbb::parallel_for(size_t{0}, site_count, [&](size_t i) {
    if (bar.cancelled()) return;
    bool was_reused = false;
    sites[i] = EnsureSiteUnit(run, i, bar.Site(i), &was_reused);
    reused[i] = was_reused;
    bar.SiteDone(i);
  });
  if (bar.cancelled()) throw Error("cancelled during the site units");
  for (const char r : reused) (r ? summary.sites_reused : summary.sites_computed)++;
  return sites;
}

// The legs: every first pass, the second pass with the first passes' pooled variance factor
// (MissionRunOptions::rock_variance_pass; a leg is matched again only when the factor it was
// matched with is not the one wanted), then the legs tested against each other (a leg the test
// changed is read from adjustment/rock_ties/).
struct LegStage {
  std::vector<LegUnitResult> legs;
  PooledVarianceFactor first_pass;
  std::optional<double> variance_pass;  // The factor the second pass applied.
  std::vector<fs::path> tie_files;      // Each leg's tie points for the adjustment.
};

LegStage RunLegStage(const RunContext& run, RunProgress& bar, MissionRunSummary& summary) {
  const size_t site_count = run.mission->sites.size();
  const size_t leg_count = site_count > 0 ? site_count - 1 : 0;
  SiteRocksCache site_rocks(run);
  LegStage stage;
  stage.legs.resize(leg_count);
  for (size_t i = 0; i < leg_count; ++i) {
    bool was_reused = false;
    stage.legs[i] = EnsureLegUnit(
        run, i, site_rocks, bar.Leg(i, leg_count, RunProgress::kSites, RunProgress::kFirstPass),
        &was_reused);
    ++(was_reused ? summary.legs_reused : summary.legs_computed);
  }
  stage.first_pass = FirstPassTieVariance(stage.legs);
  stage.variance_pass = SecondPassFactor(run, stage.legs);
  for (size_t i = 0; i < leg_count; ++i) {
    if (EnsureLegSecondPass(run, i, site_rocks, stage.variance_pass, stage.legs[i],
                            bar.Leg(i, leg_count, RunProgress::kFirstPass, RunProgress::kLegs))) {
      ++summary.legs_rematched;
    }
  }
  stage.tie_files =
      TestLegsAgainstEachOther(run, stage.legs, run.out_dir / "adjustment" / "rock_ties");
  return stage;
}

// The adjustment's inputs and options: network.json written, each site's own control points.
AdjustmentInputs PrepareAdjustment(const RunContext& run, const LegStage& legs) {
  const MissionManifest& mission = *run.mission;
  AdjustmentInputs adjustment;
  adjustment.dir = run.out_dir / "adjustment";
  fs::create_directories(adjustment.dir);
  WriteFileAtomically(adjustment.dir / "network.json", NetworkJson(mission, *run.options).dump(2));
  for (const MissionSite& site : mission.sites) {
    adjustment.site_controls.push_back(SiteDir(run, site.site) / "control_points.json");
  }
  adjustment.leg_tie_files = legs.tie_files;
  adjustment.options.bundle = run.options->bundle;
  // The second pass's variance factor decides which legs fault detection accepts; the
  // adjustment weighs their tie points by the a-priori covariances: scaling the rock ties there
  // left the site errors as they were and made their sigmas less honest on three generated
  // traverses (docs/rocks.md).
  if (legs.variance_pass) adjustment.options.rock_tie_variance_factor = 1.0 / *legs.variance_pass;
  if (const MissionOrbitalProduct* image = mission.FirstOrbital("image")) {
    adjustment.options.orbital_image = image->path;
  }
  return adjustment;
}

// The products unit with the adjusted poses: computed, or reused when it was made with the same
// poses; `*unit` says which. Nullopt when products are off.
std::optional<ProductsUnitResult> EnsureProductsUnit(const RunContext& run,
                                                     const ProgressCallback& progress,
                                                     std::string* unit) {
  const size_t site_count = run.mission->sites.size();
  if (!run.options->traverse_products || site_count == 0) return std::nullopt;
  const std::vector<Rigid3d> poses =
      AdjustedPoses(run.out_dir / "adjustment" / "adjustment.json", site_count);
  const fs::path dir = run.out_dir / "products";
  std::optional<ProductsUnitResult> products = FinishedUnitResult<ProductsUnitResult>(run, dir);
  *unit = "reused";
  if (!products || !SamePoses(products->poses, poses)) {
    *unit = "computed";
    products = MakeTraverseProducts(run, poses, progress);
    FinishUnit(run, dir, products->ToJson());
  }
  products->poses.clear();  // In products/unit.json; summary.json keeps the figures.
  return products;
}

// What each stage cost when its units were computed (this run or an earlier one), from the
// units' records: per-site stages and legs summed (sites ran two or more at a time).
std::map<std::string, double> ComputedSeconds(const std::vector<SiteUnitResult>& sites,
                                              const std::vector<LegUnitResult>& legs,
                                              const std::optional<CratersUnitResult>& craters,
                                              double adjustment_seconds,
                                              const std::optional<ProductsUnitResult>& products) {
  std::map<std::string, double> computed;
  for (const char* stage : {"stereo", "dtm", "ortho", "registration"}) {
    double sum = 0.0;
    for (const SiteUnitResult& site : sites) {
      const auto found = site.seconds.find(stage);
      if (found != site.seconds.end()) sum += found->second;
    }
    computed[stage] = sum;
  }
  double legs_seconds = 0.0;
  for (const LegUnitResult& leg : legs) legs_seconds += leg.match.seconds.value_or(0.0);
  computed["legs"] = legs_seconds;
  computed["craters"] = craters ? craters->seconds : 0.0;
  computed["adjustment"] = adjustment_seconds;
  double products_seconds = 0.0;
  if (products) {
    for (const auto& [part, value] : products->seconds) products_seconds += value;
  }
  computed["products"] = products_seconds;
  return computed;
}

}  // namespace
}  // namespace mission_run

MissionRunSummary RunMission(const MissionManifest& mission, const std::filesystem::path& out_dir,
                             const MissionRunOptions& options, const ProgressCallback& progress) {
  using namespace mission_run;
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  fs::create_directories(out_dir);
  const RunContext run(mission, options, out_dir);
  RunProgress bar(progress, std::max<size_t>(1, mission.sites.size()));
  // Wall time of each stage of this invocation [s] (reused units cost ~0).
  std::map<std::string, double> stage_seconds;
  auto clock = std::chrono::steady_clock::now();
  const auto lap = [&](const char* stage) {
    stage_seconds[stage] = SecondsSince(clock);
    clock = std::chrono::steady_clock::now();
  };

  MissionRunSummary summary;
  const std::vector<SiteUnitResult> sites = RunSiteStage(run, bar, summary);
  lap("sites");
  const LegStage legs = RunLegStage(run, bar, summary);
  lap("legs");
  // How the whole-run units went: "computed", "reused" or "off".
  std::string craters_unit = "off", products_unit = "off";
  std::optional<CratersUnitResult> craters;
  if (options.detect_craters) {
    bool was_reused = false;
    craters =
        EnsureCratersUnit(run, bar.Span(RunProgress::kLegs, RunProgress::kCraters), &was_reused);
    craters_unit = was_reused ? "reused" : "computed";
  }
  lap("craters");
  // The adjustment reads everything the units wrote: the network, every site's control
  // points and every leg's tie points.
  AdjustmentInputs adjustment = PrepareAdjustment(run, legs);
  AdjustmentResult adjusted =
      AdjustTraverse(adjustment, bar.Span(RunProgress::kCraters, RunProgress::kAdjustment));
  lap("adjustment");
  const GuidedPassesResult guided = RunGuidedPasses(run, sites, adjustment, adjusted, [&] {
    bar.Report(RunProgress::kAdjustment, "guided registration");
  });
  lap("guided_registration");
  const std::optional<ProductsUnitResult> products =
      EnsureProductsUnit(run, bar.Span(RunProgress::kAdjustment, 1.0), &products_unit);
  lap("products");
  bar.Report(1.0, "done");

  RunSummary& record = summary.record;
  record.mission = mission.root.string();
  record.name = mission.name;
  record.sites = sites;
  record.legs = legs.legs;
  record.tie_variance = TieVariance(legs.first_pass, legs.variance_pass);
  record.craters = craters;
  record.adjustment = adjusted;
  record.guided = guided;
  record.products = products;
  record.units = UnitsSummary{summary.sites_computed, summary.sites_reused,   summary.legs_computed,
                              summary.legs_reused,    summary.legs_rematched, craters_unit,
                              products_unit};
  record.stage_seconds = stage_seconds;
  record.computed_seconds =
      ComputedSeconds(sites, legs.legs, craters, stage_seconds["adjustment"], products);
  record.seconds = SecondsSince(start);
  summary.json = record.ToJson();
  return summary;
}

MissionRunSummary RunMissionFolder(const std::filesystem::path& mission,
                                   const std::filesystem::path& out_dir,
                                   const MissionRunOptions& options, bool overwrite,
                                   const ProgressCallback& progress) {
  options.Check();  // Bad options fail before the mission is read.
  // In place: the run's units are files under out_dir that a later run resumes from. The lock
  // keeps a second run on the same out_dir from computing them all again at the same time.
  OutputFolder out(out_dir, mission_run::RunFolderPolicy(mission, overwrite));
  // Every file the manifest names is checked before any work starts.
  const MissionManifest manifest = ReadMissionManifest(mission);
  MissionRunSummary summary = RunMission(manifest, out.dir(), options, progress);
  summary.record.command = "run";
  summary.json = summary.record.ToJson();
  WriteFileAtomically(out.dir() / "summary.json", summary.json.dump(2) + "\n");
  WriteRunReport(out.dir());
  out.Commit();
  return summary;
}

}  // namespace areomap
