// Private plumbing of RunMission (mission_run.h): the unit folders, their completion markers, and
// the per-unit stages. Each stage reads its inputs from the mission or from earlier units' files
// and writes its products atomically, its unit.json last.
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "areomap/map/dtm.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/site_georeference.h"
#include "areomap/registration/mission_run.h"

namespace areomap::mission_run {

// The shared context of one run.
struct RunContext {
  const MissionManifest* mission;
  const MissionRunOptions* options;
  std::filesystem::path out_dir;
  std::string fingerprint;  // Options + mission, recorded in every unit.json.
  MapFrame map;             // The mission map (equirectangular at the origin).

  RunContext(const MissionManifest& mission_in, const MissionRunOptions& options_in,
             std::filesystem::path out_dir_in);
};

std::filesystem::path SiteDir(const RunContext& run, int site);
std::filesystem::path LegDir(const RunContext& run, int site_a, int site_b);

// The unit's recorded summary when it finished with this run's fingerprint, else null.
nlohmann::json FinishedUnit(const RunContext& run, const std::filesystem::path& unit_dir);
// Marks the unit finished: writes unit.json = {fingerprint, summary} atomically.
void FinishUnit(const RunContext& run, const std::filesystem::path& unit_dir,
                const nlohmann::json& summary);

// Where telemetry puts a site: traverse_from_site with the believed (level, north-up) frame.
Rigid3d TelemetryTraverseFromSite(const MissionSitePose& pose);
// Distance driven from site 0 to `site_index` along the telemetry traverse [m].
double DrivenDistance(const MissionManifest& mission, size_t site_index);

// Stage of one site (index into mission.sites): stereo, DTM, orthophoto, orbital registration.
nlohmann::json RunSiteUnit(const RunContext& run, size_t site_index,
                           const ProgressCallback& progress);
// Stage of one leg (consecutive site indices): rocks, matching, fault detection, tie points.
nlohmann::json RunLegUnit(const RunContext& run, size_t index_a, size_t index_b,
                          const ProgressCallback& progress);

}  // namespace areomap::mission_run
