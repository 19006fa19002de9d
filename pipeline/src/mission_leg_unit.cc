// One leg of a mission run (two consecutive sites): rocks extracted from both sites' clouds,
// matched across the sites with fault detection (ch. 3.2, 4.2), tie points for the adjustment.
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>

#include "areomap/landmarks/rock_matching.h"
#include "areomap/map/error.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/pipeline/rock_pair.h"
#include "mission_units.h"

namespace areomap::mission_run {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A site's pose in the mission frame as corrected by its orbital registration (registration.json
// of the site unit): position shifted by the match, heading turned by the solved rotation (a
// counter-clockwise rotation on the map is a heading decrease). Null when the registration was not
// confident or did not solve the rotation. Its 1-sigma errors: horizontal position, the match's
// shift sigma (at least a quarter orbital pixel); heading, half the rotation grid step, or a whole
// step when the rotation sits at the edge of the searched range (its refinement was clamped there).
struct RegisteredSite {
  Rigid3d traverse_from_site;
  double position_sigma_m = 0.0;
  double heading_sigma_deg = 0.0;
};

std::optional<RegisteredSite> RegisteredTraverseFromSite(const MissionRunContext& run, int site,
                                                         const MissionSitePose& telemetry) {
  const fs::path path = SiteDir(run, site) / "registration.json";
  if (!fs::exists(path)) return std::nullopt;
  const json recorded = ReadJsonOrNull(path);
  if (!recorded.is_object()) return std::nullopt;
  const SiteRegistrationResult reg = SiteRegistrationResult::FromJson(recorded, path.string());
  if (!reg.matched || !reg.rotation_deg) return std::nullopt;
  const OrbitalMatchOptions& match = run.options->match;
  const double north = reg.shift_north_m.value_or(0.0), east = reg.shift_east_m.value_or(0.0);
  const double rotation_deg = *reg.rotation_deg;
  RegisteredSite out;
  out.position_sigma_m = std::max({reg.sigma_north_m.value_or(0.0), reg.sigma_east_m.value_or(0.0),
                                   0.25 * reg.gsd_m.value_or(0.0)});
  const bool at_edge =
      std::abs(rotation_deg) >= match.max_rotation_deg - 0.5 * match.rotation_step_deg - 1e-9;
  out.heading_sigma_deg = (at_edge ? 1.0 : 0.5) * match.rotation_step_deg;
  if (!std::isfinite(north) || !std::isfinite(east) || !std::isfinite(rotation_deg) ||
      !std::isfinite(out.position_sigma_m)) {
    return std::nullopt;
  }
  const Eigen::Vector3d position = telemetry.position + Eigen::Vector3d(north, east, 0.0);
  const double rotation = rotation_deg * std::numbers::pi / 180.0;
  out.traverse_from_site =
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(-rotation, Eigen::Vector3d::UnitZ())), position);
  return out;
}

// The leg's prior for the rock search: from both sites' registration-corrected poses when both
// registrations are confident and agree with telemetry within three combined sigmas, else from
// telemetry (dead reckoning: leg_scale_sigma x length, leg_heading_sigma_deg). `info` records
// which and why.
RockMatchingPrior LegPrior(const MissionRunContext& run, size_t index_a, size_t index_b,
                           LegPriorRecord* info) {
  const MissionManifest& mission = *run.mission;
  const MissionRunOptions& options = *run.options;
  RockMatchingPrior telemetry;
  telemetry.a_from_b = TelemetryTraverseFromSite(mission.telemetry[index_a]).Inverse() *
                       TelemetryTraverseFromSite(mission.telemetry[index_b]);
  telemetry.position_sigma_m =
      options.leg_scale_sigma * telemetry.a_from_b.translation.head<2>().norm();
  telemetry.heading_sigma_deg = options.leg_heading_sigma_deg;
  telemetry.source = "telemetry";
  const std::optional<RegisteredSite> reg_a =
      RegisteredTraverseFromSite(run, mission.sites[index_a].site, mission.telemetry[index_a]);
  const std::optional<RegisteredSite> reg_b =
      RegisteredTraverseFromSite(run, mission.sites[index_b].site, mission.telemetry[index_b]);
  *info = LegPriorRecord{};
  info->source = "telemetry";
  if (!reg_a || !reg_b) {
    info->reason = "orbital registration not confident at both sites";
  } else {
    RockMatchingPrior registered;
    registered.a_from_b = reg_a->traverse_from_site.Inverse() * reg_b->traverse_from_site;
    registered.position_sigma_m = std::hypot(reg_a->position_sigma_m, reg_b->position_sigma_m);
    registered.heading_sigma_deg = std::hypot(reg_a->heading_sigma_deg, reg_b->heading_sigma_deg);
    registered.source = "orbital registration";
    const double shift =
        (registered.a_from_b.translation - telemetry.a_from_b.translation).head<2>().norm();
    const double turn =
        Eigen::AngleAxisd(registered.a_from_b.rotation * telemetry.a_from_b.rotation.conjugate())
            .angle() *
        180.0 / std::numbers::pi;
    const double shift_limit =
        3.0 * std::sqrt(2.0) * std::hypot(telemetry.position_sigma_m, registered.position_sigma_m);
    const double turn_limit =
        3.0 * std::hypot(telemetry.heading_sigma_deg, registered.heading_sigma_deg);
    info->registration_minus_telemetry_m = shift;
    info->registration_minus_telemetry_deg = turn;
    if (shift <= shift_limit && turn <= turn_limit) {
      info->source = registered.source;
      telemetry = registered;
    } else {
      info->reason = "orbital registration disagrees with telemetry beyond 3 sigma";
    }
  }
  // The prior pose itself (site b in site a: translation and turn about z, down), so that a run
  // can be re-matched offline (bench/rock_funnel_bench.cc).
  const Eigen::Matrix3d r = telemetry.a_from_b.RotationMatrix();
  const Eigen::Vector3d& t = telemetry.a_from_b.translation;
  info->a_from_b_translation_m = std::array<double, 3>{t.x(), t.y(), t.z()};
  info->a_from_b_turn_deg = std::atan2(r(1, 0), r(0, 0)) * 180.0 / std::numbers::pi;
  info->position_sigma_m = telemetry.position_sigma_m;
  info->heading_sigma_deg = telemetry.heading_sigma_deg;
  return telemetry;
}

}  // namespace

const SiteRocksCache::Entry& SiteRocksCache::Get(size_t site_index) {
  const auto found = entries_.find(site_index);
  if (found != entries_.end()) return found->second;
  const int site = run_->mission->sites.at(site_index).site;
  const PointCloud cloud = ReadPointCloudPly(SiteDir(*run_, site) / "points.ply");
  Entry entry;
  entry.rocks.site = site;
  entry.rocks.camera_center = cloud.camera_center;
  entry.rocks.rocks = ExtractRocks(cloud, run_->options->rocks, &entry.summary);
  return entries_.emplace(site_index, std::move(entry)).first->second;
}

LegUnitResult RunLegUnit(const MissionRunContext& run, size_t index_a, size_t index_b,
                         SiteRocksCache& rocks, const RockMatchingOptions& matching,
                         const ProgressCallback& progress) {
  const MissionManifest& mission = *run.mission;
  const int site_a = mission.sites.at(index_a).site;
  const int site_b = mission.sites.at(index_b).site;
  const fs::path dir = LegDir(run, site_a, site_b);
  fs::create_directories(dir);

  const SiteRocksCache::Entry& a = rocks.Get(index_a);
  if (progress && !progress(0.4, "rocks")) throw Error("cancelled during rock extraction");
  const SiteRocksCache::Entry& b = rocks.Get(index_b);
  if (progress && !progress(0.8, "rocks")) throw Error("cancelled during rock extraction");
  const SiteRocks& rocks_a = a.rocks;
  const SiteRocks& rocks_b = b.rocks;

  LegUnitResult leg;
  leg.prior.emplace();
  const RockMatchingPrior prior = LegPrior(run, index_a, index_b, &*leg.prior);
  const SitePairMatch match = MatchRockPair(rocks_a, rocks_b, prior, matching, dir);
  if (progress) progress(1.0, "matching");

  leg.site_a = site_a;
  leg.site_b = site_b;
  leg.telemetry_distance_m =
      (mission.telemetry[index_b].position - mission.telemetry[index_a].position).head<2>().norm();
  leg.match.outcome = ToString(match.report.outcome);
  leg.match.tie_points = static_cast<int64_t>(match.tie_points.size());
  leg.match.rock_matches = static_cast<int64_t>(match.matches.size());
  leg.rocks_a = a.summary;
  leg.rocks_b = b.summary;
  leg.faults = match.report;
  if (match.error) {
    leg.match.relative_error_percent = match.error->relative_error_percent;
    // The conformal fit's residuals, pooled over the legs into the run's a-posteriori variance
    // factor of the rock tie points (mission_run.cc, FirstPassTieVariance).
    leg.match.conformal_chi2 = match.error->chi2;
    leg.match.conformal_redundancy = match.error->redundancy;
  }
  leg.match.tie_variance_factor = matching.tie_variance_factor;
  return leg;
}

}  // namespace areomap::mission_run
