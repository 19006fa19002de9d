#include "areomap/map/mission_manifest.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>

#include <nlohmann/json.hpp>

#include "areomap/map/csv.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr double kRadPerDeg = std::numbers::pi / 180.0;

// Reads `key` of `object` as T, or throws naming the manifest and the key path.
template <typename T>
T Get(const json& object, const std::string& key, const std::string& where,
      const fs::path& manifest) {
  if (!object.is_object() || !object.contains(key)) {
    throw Error(manifest.string() + ": missing key \"" + where + key + "\"");
  }
  try {
    return object.at(key).get<T>();
  } catch (const json::exception&) {
    throw Error(manifest.string() + ": key \"" + where + key + "\" has the wrong type");
  }
}

// Reads `key` of `object` as an integer in [lo, hi] (not 1.5, not 1e20), or throws naming it.
int GetInteger(const json& object, const std::string& key, const std::string& where,
               const fs::path& manifest, int lo, int hi) {
  const json value = Get<json>(object, key, where, manifest);
  if (!value.is_number_integer() ||
      (value.is_number_unsigned() ? value.get<unsigned long long>() > static_cast<unsigned>(hi)
                                  : value.get<long long>() < lo || value.get<long long>() > hi)) {
    throw Error(manifest.string() + ": key \"" + where + key + "\" is " + value.dump() +
                "; expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) +
                "]");
  }
  return value.get<int>();
}

// Reads `key` of `object` as a finite number in [lo, hi], or throws naming it and the rule.
double GetNumber(const json& object, const std::string& key, const std::string& where,
                 const fs::path& manifest, double lo, double hi, const std::string& rule) {
  const json value = Get<json>(object, key, where, manifest);
  if (!value.is_number() || !(value.get<double>() >= lo && value.get<double>() <= hi)) {
    throw Error(manifest.string() + ": key \"" + where + key + "\" is " + value.dump() +
                "; expected " + rule);
  }
  return value.get<double>();
}

fs::path ExistingFile(const fs::path& root, const std::string& relative, const std::string& key,
                      const fs::path& manifest) {
  const fs::path path = root / relative;
  if (!fs::is_regular_file(path)) {
    throw Error(manifest.string() + ": " + key + " refers to " + path.string() +
                ", which does not exist");
  }
  return path;
}

double ParseNumber(const std::string& text, const fs::path& csv, int line, const std::string& col) {
  try {
    size_t used = 0;
    const double value = std::stod(text, &used);
    if (used == text.size() && std::isfinite(value)) return value;
  } catch (const std::exception&) {
  }
  throw Error(csv.string() + ": line " + std::to_string(line) + ", column " + col +
              ": expected a finite number, got \"" + text + "\"");
}

// Splits "NAVCAM_LEFT" into ("NAVCAM", "LEFT"); throws for other suffixes.
std::pair<std::string, std::string> SplitInstrument(const std::string& id,
                                                    const fs::path& manifest) {
  const size_t underscore = id.rfind('_');
  const std::string side = underscore == std::string::npos ? "" : id.substr(underscore + 1);
  if (side != "LEFT" && side != "RIGHT") {
    throw Error(manifest.string() + ": instrument \"" + id +
                "\" is not a stereo camera; expected a name ending in _LEFT or _RIGHT");
  }
  return {id.substr(0, underscore), side};
}

MissionSite ReadSite(const json& entry, const fs::path& root, const fs::path& manifest) {
  MissionSite site;
  site.site = GetInteger(entry, "site", "sites[].", manifest, 0, 999999);
  const std::string where = "sites[" + std::to_string(site.site) + "].images[].";
  // Keyed by (instrument, pair): a site may hold a Navcam and a Pancam panorama.
  std::map<std::pair<std::string, int>, MissionStereoPair> pairs;
  std::map<std::pair<std::string, int>, int> sides_seen;
  for (const json& image : Get<json>(entry, "images", "sites[].", manifest)) {
    const auto [instrument, side] =
        SplitInstrument(Get<std::string>(image, "instrument", where, manifest), manifest);
    const int index = GetInteger(image, "pair", where, manifest, 0, 65535);
    const std::pair<std::string, int> key(instrument, index);
    MissionStereoPair& pair = pairs[key];
    pair.pair = index;
    pair.instrument = instrument;
    const fs::path picture = ExistingFile(root, Get<std::string>(image, "image", where, manifest),
                                          where + "image", manifest);
    const fs::path label = ExistingFile(root, Get<std::string>(image, "label", where, manifest),
                                        where + "label", manifest);
    (side == "LEFT" ? pair.left_image : pair.right_image) = picture;
    (side == "LEFT" ? pair.left_label : pair.right_label) = label;
    sides_seen[key] |= side == "LEFT" ? 1 : 2;
  }
  for (const auto& [key, pair] : pairs) {
    if (sides_seen[key] != 3) {
      throw Error(manifest.string() + ": site " + std::to_string(site.site) + " " + key.first +
                  " pair " + std::to_string(key.second) + " lacks its " +
                  (sides_seen[key] == 1 ? "right" : "left") + " image");
    }
    site.pairs.push_back(pair);
  }
  return site;
}

void CheckFormatAndVersion(const json& root_json, const fs::path& manifest) {
  if (Get<std::string>(root_json, "format", "", manifest) != "areomap-mission") {
    throw Error(manifest.string() + ": \"format\" is not \"areomap-mission\"");
  }
  if (const int version = GetInteger(root_json, "version", "", manifest, 0, 1000000);
      version != 1) {
    throw Error(manifest.string() + ": version " + std::to_string(version) +
                " is not supported; expected 1");
  }
}

Body ReadBody(const json& body_json, const fs::path& manifest) {
  Body body;
  body.name = Get<std::string>(body_json, "name", "body.", manifest);
  constexpr double kHuge = 1e12;  // [m], any body's radius is below it
  body.a = GetNumber(body_json, "a_m", "body.", manifest, 1.0, kHuge,
                     "a finite equatorial radius > 0 [m]");
  body.b = GetNumber(body_json, "b_m", "body.", manifest, 1.0, body.a,
                     "a finite polar radius in (0, a_m] [m]");
  return body;
}

Geographic ReadOrigin(const json& origin_json, const fs::path& manifest) {
  Geographic origin;
  origin.lat = GetNumber(origin_json, "lat_deg", "origin.", manifest, -90.0, 90.0,
                         "a latitude in [-90, 90]") *
               kRadPerDeg;
  origin.lon = GetNumber(origin_json, "lon_deg", "origin.", manifest, -360.0, 360.0,
                         "a longitude in [-360, 360]") *
               kRadPerDeg;
  // Heights above the ellipsoid: Olympus Mons is 22 km up, Hellas 8 km down.
  origin.h = GetNumber(origin_json, "h_m", "origin.", manifest, -1e5, 1e5,
                       "a height in [-100000, 100000] m above the ellipsoid");
  return origin;
}

MissionOrbitalProduct ReadOrbitalProduct(const json& product, const fs::path& root,
                                         const fs::path& manifest) {
  MissionOrbitalProduct p;
  p.id = Get<std::string>(product, "id", "orbital[].", manifest);
  p.kind = Get<std::string>(product, "kind", "orbital[].", manifest);
  if (p.kind != "image" && p.kind != "dtm") {
    throw Error(manifest.string() + ": orbital[" + p.id + "].kind is \"" + p.kind +
                "\"; expected \"image\" or \"dtm\"");
  }
  p.path = ExistingFile(root, Get<std::string>(product, "path", "orbital[].", manifest),
                        "orbital[" + p.id + "].path", manifest);
  p.gsd_m = GetNumber(product, "gsd_m", "orbital[].", manifest, 1e-6, 1e6,
                      "a ground sample distance in (0, 1e6] m");
  if (product.contains("sun_azimuth_deg")) {
    p.sun_azimuth_deg = GetNumber(product, "sun_azimuth_deg", "orbital[].", manifest, -360.0, 360.0,
                                  "an azimuth in [-360, 360] degrees from north");
  }
  if (product.contains("sun_elevation_deg")) {
    p.sun_elevation_deg = GetNumber(product, "sun_elevation_deg", "orbital[].", manifest, -90.0,
                                    90.0, "an elevation in [-90, 90] degrees");
  }
  return p;
}

// The "sites" list: at least one, each site number once.
std::vector<MissionSite> ReadSites(const json& root_json, const fs::path& root,
                                   const fs::path& manifest) {
  std::vector<MissionSite> sites;
  for (const json& site : Get<json>(root_json, "sites", "", manifest)) {
    sites.push_back(ReadSite(site, root, manifest));
  }
  if (sites.empty()) throw Error(manifest.string() + ": \"sites\" is empty");
  for (size_t i = 0; i < sites.size(); ++i) {
    for (size_t j = 0; j < i; ++j) {
      if (sites[j].site == sites[i].site) {
        throw Error(manifest.string() + ": sites[" + std::to_string(i) + "].site " +
                    std::to_string(sites[i].site) + " repeats sites[" + std::to_string(j) +
                    "]; expected each site once");
      }
    }
  }
  return sites;
}

// Reads the telemetry poses into `mission` (one per site, in the sites' order); returns the CSV.
fs::path ReadTelemetry(const json& root_json, const fs::path& manifest, MissionManifest* mission) {
  const json& telemetry = Get<json>(root_json, "telemetry", "", manifest);
  const fs::path telemetry_csv =
      ExistingFile(mission->root, Get<std::string>(telemetry, "sites", "telemetry.", manifest),
                   "telemetry.sites", manifest);
  mission->telemetry = ReadSitePosesCsv(telemetry_csv);
  for (size_t i = 0; i < mission->sites.size(); ++i) {
    if (i >= mission->telemetry.size() || mission->telemetry[i].site != mission->sites[i].site) {
      throw Error(manifest.string() + ": telemetry has no pose for site " +
                  std::to_string(mission->sites[i].site) + " (row " + std::to_string(i + 1) + ")");
    }
  }
  return telemetry_csv;
}

// Reads the optional "truth" entries into `mission`; returns the truth sites CSV, if any.
std::optional<fs::path> ReadTruth(const json& root_json, const fs::path& manifest,
                                  MissionManifest* mission) {
  std::optional<fs::path> truth_sites_csv;
  if (!root_json.contains("truth")) return truth_sites_csv;
  const json& truth = root_json["truth"];
  if (truth.contains("sites")) {
    truth_sites_csv =
        ExistingFile(mission->root, Get<std::string>(truth, "sites", "truth.", manifest),
                     "truth.sites", manifest);
    mission->truth_sites = ReadSitePosesCsv(*truth_sites_csv);
  }
  if (truth.contains("craters")) {
    mission->truth_craters_csv =
        ExistingFile(mission->root, Get<std::string>(truth, "craters", "truth.", manifest),
                     "truth.craters", manifest);
  }
  if (truth.contains("rocks")) {
    mission->truth_rocks_csv =
        ExistingFile(mission->root, Get<std::string>(truth, "rocks", "truth.", manifest),
                     "truth.rocks", manifest);
  }
  return truth_sites_csv;
}

// Every file the manifest names, mission.json first.
std::vector<fs::path> ListMissionFiles(const MissionManifest& mission, const fs::path& manifest,
                                       const fs::path& telemetry_csv,
                                       const std::optional<fs::path>& truth_sites_csv) {
  std::vector<fs::path> files = {manifest, telemetry_csv};
  for (const MissionOrbitalProduct& p : mission.orbital) files.push_back(p.path);
  for (const MissionSite& site : mission.sites) {
    for (const MissionStereoPair& pair : site.pairs) {
      files.insert(files.end(),
                   {pair.left_image, pair.left_label, pair.right_image, pair.right_label});
    }
  }
  for (const auto& csv : {truth_sites_csv, mission.truth_craters_csv, mission.truth_rocks_csv}) {
    if (csv) files.push_back(*csv);
  }
  return files;
}

}  // namespace

const MissionOrbitalProduct* MissionManifest::FirstOrbital(const std::string& kind) const {
  for (const MissionOrbitalProduct& product : orbital) {
    if (product.kind == kind) return &product;
  }
  return nullptr;
}

std::vector<MissionSitePose> ReadSitePosesCsv(const fs::path& csv) {
  std::ifstream in(csv);
  if (!in) throw Error(csv.string() + ": cannot open the site poses CSV");
  return ReadSitePosesCsv(in, csv);
}

std::vector<MissionSitePose> ReadSitePosesCsv(std::istream& in, const fs::path& csv) {
  std::string line;
  if (!std::getline(in, line)) throw Error(csv.string() + ": empty; expected a header row");
  const std::vector<std::string> header = SplitCsvLine(line);
  const std::vector<std::string> wanted = {"site", "north_m", "east_m", "down_m", "heading_deg"};
  if (header.size() < wanted.size() || !std::equal(wanted.begin(), wanted.end(), header.begin())) {
    throw Error(csv.string() + ": header must start with site,north_m,east_m,down_m,heading_deg");
  }
  std::vector<MissionSitePose> poses;
  for (int line_number = 2; std::getline(in, line); ++line_number) {
    if (line.empty()) continue;
    const std::vector<std::string> f = SplitCsvLine(line);
    if (f.size() < wanted.size()) {
      throw Error(csv.string() + ": line " + std::to_string(line_number) + " has " +
                  std::to_string(f.size()) + " fields; expected at least 5");
    }
    MissionSitePose pose;
    const double site = ParseNumber(f[0], csv, line_number, "site");
    if (!(site >= 0.0 && site <= 999999.0 && site == std::floor(site))) {
      throw Error(csv.string() + ": line " + std::to_string(line_number) +
                  ", column site: expected an integer in [0, 999999], got \"" + f[0] + "\"");
    }
    pose.site = static_cast<int>(site);
    pose.position = {ParseNumber(f[1], csv, line_number, "north_m"),
                     ParseNumber(f[2], csv, line_number, "east_m"),
                     ParseNumber(f[3], csv, line_number, "down_m")};
    pose.heading = ParseNumber(f[4], csv, line_number, "heading_deg") * kRadPerDeg;
    poses.push_back(pose);
  }
  return poses;
}

MissionManifest ReadMissionManifest(const fs::path& path) {
  if (!fs::exists(path)) {
    throw Error(path.string() +
                ": no such mission folder or mission.json; expected the folder "
                "`areomap simulate` writes (docs/mission-format.md)");
  }
  const fs::path manifest = fs::is_directory(path) ? path / "mission.json" : path;
  std::ifstream in(manifest);
  if (!in) throw Error(manifest.string() + ": cannot open the mission manifest");
  return ReadMissionManifest(in, manifest);
}

MissionManifest ReadMissionManifest(std::istream& in, const fs::path& manifest) {
  const json root_json = json::parse(in, nullptr, false);
  if (root_json.is_discarded()) throw Error(manifest.string() + ": not valid JSON");
  CheckFormatAndVersion(root_json, manifest);
  MissionManifest mission;
  mission.root = manifest.parent_path();
  // Optional, but text when given (json::value would throw its own type_error).
  if (root_json.contains("name")) mission.name = Get<std::string>(root_json, "name", "", manifest);
  mission.body = ReadBody(Get<json>(root_json, "body", "", manifest), manifest);
  mission.origin = ReadOrigin(Get<json>(root_json, "origin", "", manifest), manifest);
  for (const json& product : Get<json>(root_json, "orbital", "", manifest)) {
    mission.orbital.push_back(ReadOrbitalProduct(product, mission.root, manifest));
  }
  mission.sites = ReadSites(root_json, mission.root, manifest);
  const fs::path telemetry_csv = ReadTelemetry(root_json, manifest, &mission);
  const std::optional<fs::path> truth_sites_csv = ReadTruth(root_json, manifest, &mission);
  mission.files = ListMissionFiles(mission, manifest, telemetry_csv, truth_sites_csv);
  return mission;
}

}  // namespace areomap
