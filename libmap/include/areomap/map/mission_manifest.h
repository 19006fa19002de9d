// Reading a mission folder (docs/mission-format.md): the manifest, its site poses and the list of
// rover stereo pairs and orbital products, every referenced file checked before any work starts.
//
// Frames: site poses are in site 0's MER site frame (x north, y east, z down [m]); headings are
// rover yaw clockwise from north [rad]. The origin is planetocentric latitude / east longitude
// [rad] and height above the body's ellipsoid [m] of site 0's frame origin.
// Failure: ReadMissionManifest throws areomap::Error naming mission.json (or the CSV) and the key
// or file that is missing or malformed; nothing is read lazily later.
#pragma once

#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "areomap/map/body.h"
#include "areomap/map/geodesy.h"

namespace areomap {

struct MissionStereoPair {
  int pair = 0;                      // Pointing index within the site's panorama.
  std::string instrument;            // e.g. "NAVCAM" (the common prefix of LEFT/RIGHT).
  std::filesystem::path left_image;  // Absolute paths.
  std::filesystem::path left_label;
  std::filesystem::path right_image;
  std::filesystem::path right_label;
};

struct MissionSite {
  int site = 0;
  std::vector<MissionStereoPair> pairs;  // Sorted by instrument, then pair index.
};

struct MissionOrbitalProduct {
  std::string id;
  std::string kind;  // "image" or "dtm".
  std::filesystem::path path;
  double gsd_m = 0.0;
  std::optional<double> sun_azimuth_deg;  // Images: clockwise from north.
  std::optional<double> sun_elevation_deg;
};

struct MissionSitePose {
  int site = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // In site 0's frame [m].
  double heading = 0.0;                                // [rad], clockwise from north.
};

struct MissionManifest {
  std::filesystem::path root;  // The mission folder.
  std::string name;
  Body body;
  Geographic origin;  // Planetocentric, east, radians; h [m].
  std::vector<MissionSite> sites;
  std::vector<MissionOrbitalProduct> orbital;
  std::vector<MissionSitePose> telemetry;    // One per site, same order as `sites`.
  std::vector<MissionSitePose> truth_sites;  // Empty when the mission has no truth.
  std::optional<std::filesystem::path> truth_craters_csv;
  std::optional<std::filesystem::path> truth_rocks_csv;
  // Every file the manifest names, mission.json first (what a run's results depend on).
  std::vector<std::filesystem::path> files;

  const MissionOrbitalProduct* FirstOrbital(const std::string& kind) const;  // nullptr if none.
};

// `path` is the mission folder or its mission.json.
MissionManifest ReadMissionManifest(const std::filesystem::path& path);
// The manifest's text from `in`; `manifest` names it in errors and the files it refers to are
// looked up beside it.
MissionManifest ReadMissionManifest(std::istream& in, const std::filesystem::path& manifest);

// Reads `site, north_m, east_m, down_m, heading_deg` rows (telemetry/sites.csv, truth/sites.csv).
std::vector<MissionSitePose> ReadSitePosesCsv(const std::filesystem::path& csv);
std::vector<MissionSitePose> ReadSitePosesCsv(std::istream& in, const std::filesystem::path& csv);

}  // namespace areomap
