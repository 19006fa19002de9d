// What the benches that judge a finished `areomap run` against a generated mission's truth
// read first: the mission (with its truth/sites.csv), its orbital image and the run's JSON.
#pragma once

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/site_georeference.h"
#include "areomap/registration/orbital_image.h"

namespace areomap::bench {

// Throws areomap::Error naming the file when it cannot be opened or parsed.
inline nlohmann::json ReadJson(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open");
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) throw Error(path.string() + ": not JSON");
  return j;
}

// The mission; throws areomap::Error when it has no truth for its sites.
inline MissionManifest ReadMissionWithTruth(const std::filesystem::path& mission_dir) {
  MissionManifest mission = ReadMissionManifest(mission_dir);
  if (mission.truth_sites.size() != mission.sites.size()) {
    throw Error(mission_dir.string() + ": the mission has no truth/sites.csv");
  }
  return mission;
}

// The mission's first orbital image; throws areomap::Error when it has none.
inline OrbitalImage OpenOrbitalImage(const MissionManifest& mission) {
  const MissionOrbitalProduct* image = mission.FirstOrbital("image");
  if (image == nullptr) throw Error(mission.root.string() + ": no orbital image");
  return OrbitalImage::Open(image->path);
}

// A site's folder name in a run (`areomap run` writes RUN/sites/site_NNN).
inline std::string SiteFolder(int site) {
  char folder[32];
  std::snprintf(folder, sizeof(folder), "site_%03d", site);
  return folder;
}

// Site `index`'s frame as the run placed it: level and north-up at its telemetry position.
inline SiteGeoreference TelemetrySiteGeoreference(const MissionManifest& mission, size_t index) {
  return SiteGeoreference::InMission(
      mission.body, mission.origin,
      Rigid3d(Eigen::Quaterniond::Identity(), mission.telemetry[index].position));
}

}  // namespace areomap::bench
