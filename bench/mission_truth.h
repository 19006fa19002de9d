// What the benches that judge a finished `areomap run` against a generated mission's truth
// read first: the mission (with its truth/sites.csv), its orbital image and the run's JSON.
#pragma once

#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
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

}  // namespace areomap::bench
