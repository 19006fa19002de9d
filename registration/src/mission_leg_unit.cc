// One leg of a mission run (two consecutive sites): rocks extracted from both sites' clouds,
// matched across the sites with fault detection (ch. 3.2, 4.2), tie points for the adjustment.
#include <string>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/registration/bundle_io.h"
#include "areomap/registration/rock_matching.h"
#include "mission_units.h"

namespace areomap::mission_run {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

SiteRocks ExtractSiteRocks(const RunContext& run, int site, RockExtractionSummary* summary) {
  const PointCloud cloud = ReadPointCloudPly(SiteDir(run, site) / "points.ply");
  SiteRocks rocks;
  rocks.site = site;
  rocks.camera_center = cloud.camera_center;
  rocks.rocks = ExtractRocks(cloud, run.options->rocks, summary);
  return rocks;
}

json ExtractionJson(const RockExtractionSummary& s) {
  return {{"points", s.points},
          {"peak_candidates", s.peak_candidates},
          {"beyond_range", s.beyond_range},
          {"too_low", s.too_low},
          {"rocks", s.rocks},
          {"modeled", s.modeled}};
}

}  // namespace

json RunLegUnit(const RunContext& run, size_t index_a, size_t index_b,
                const ProgressCallback& progress) {
  const MissionManifest& mission = *run.mission;
  const int site_a = mission.sites.at(index_a).site;
  const int site_b = mission.sites.at(index_b).site;
  const fs::path dir = LegDir(run, site_a, site_b);
  fs::create_directories(dir);

  RockExtractionSummary summary_a, summary_b;
  const SiteRocks rocks_a = ExtractSiteRocks(run, site_a, &summary_a);
  if (progress && !progress(0.4, "rocks")) throw Error("cancelled during rock extraction");
  const SiteRocks rocks_b = ExtractSiteRocks(run, site_b, &summary_b);
  if (progress && !progress(0.8, "rocks")) throw Error("cancelled during rock extraction");

  const Rigid3d a_from_b = TelemetryTraverseFromSite(mission.telemetry[index_a]).Inverse() *
                           TelemetryTraverseFromSite(mission.telemetry[index_b]);
  const SitePairMatch match = MatchSitePair(rocks_a, rocks_b, a_from_b, run.options->matching);
  WriteFileAtomically(dir / "faults.json", match.report.ToJson().dump(2));
  WriteFileAtomically(dir / "faults.txt", match.report.ToText());

  WriteFileAtomically(dir / "tie_points.json",
                      json{{"tie_points", TiePointsToJson(match.tie_points)}}.dump(2));
  if (progress) progress(1.0, "matching");

  json summary = {{"site_a", site_a},
                  {"site_b", site_b},
                  {"telemetry_distance_m", a_from_b.translation.head<2>().norm()},
                  {"outcome", ToString(match.report.outcome)},
                  {"tie_points", match.tie_points.size()},
                  {"rock_matches", match.matches.size()},
                  {"rocks_a", ExtractionJson(summary_a)},
                  {"rocks_b", ExtractionJson(summary_b)},
                  {"faults", match.report.ToJson()}};
  if (match.error) summary["relative_error_percent"] = match.error->relative_error_percent;
  return summary;
}

}  // namespace areomap::mission_run
