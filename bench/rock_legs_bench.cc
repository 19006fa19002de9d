// Rock tie points of a finished `areomap run` against the generated mission's truth: per leg, the
// prior the leg used, its rock matches, how many join the same true rock, RE and the outcome.
//
// Truth: each site frame is the rover's believed (level, north-up) frame, so a point of site k
// lies in site 0's frame at Rz(h_true - h_telemetry) p + T_true (truth/sites.csv, telemetry/).
// A peak belongs to the tallest truth rock whose footprint (base radius + 15 cm + half the peak's
// largest horizontal sigma, for the stereo range error) holds it; a match is correct when both
// peaks belong to the same truth rock. The sight-ray verdict (bench::SightRayTruth: the truth rock
// the camera's ray through the peak meets, cameras from each site's points.ply) is printed beside.
//
// Run: build/release/bench/areomap_bench_rock_legs MISSION_DIR RUN_DIR
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/map/rigid3d.h"
#include "mission_truth.h"
#include "rock_truth.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

using bench::ReadTruthRocks;
using bench::RockUnder;
using bench::TruthRock;

// The run's summary.json "legs": each leg's outcome, RE and tie points after the legs' test
// (leg_consistency.h), which the leg's own unit.json predates.
nlohmann::json RunLegs(const fs::path& run_dir) {
  std::ifstream file(run_dir / "summary.json");
  if (!file) throw Error((run_dir / "summary.json").string() + ": not found; run `areomap run`");
  return nlohmann::json::parse(file).value("legs", nlohmann::json::array());
}

int Main(const fs::path& mission_dir, const fs::path& run_dir) {
  const MissionManifest mission = ReadMissionManifest(mission_dir);
  const std::vector<Rigid3d> world_from_site = bench::TrueWorldFromSites(mission);
  const std::vector<TruthRock> truth = ReadTruthRocks(*mission.truth_rocks_csv);
  const nlohmann::json run_legs = RunLegs(run_dir);
  const bench::SightRayTruth sight(truth, mission.origin.h);
  // Site k's left camera in site 0's frame, read from its cloud when first needed.
  std::vector<std::optional<Eigen::Vector3d>> cameras(mission.sites.size());
  const auto camera = [&](size_t k) {
    if (!cameras[k]) {
      const fs::path ply =
          run_dir / "sites" / bench::SiteFolder(mission.sites[k].site) / "points.ply";
      cameras[k] = world_from_site[k] * ReadPointCloudPly(ply).camera_center;
    }
    return *cameras[k];
  };
  int all = 0, all_correct = 0, accepted = 0, accepted_correct = 0, legs_accepted = 0;
  int all_seen_right = 0, accepted_seen_right = 0;
  std::printf(
      "leg      prior                 matches correct sight  RE [%%]  outcome (after the legs' "
      "test: dropped ties)\n");
  for (size_t k = 0; k + 1 < mission.sites.size(); ++k) {
    char name[64];
    std::snprintf(name, sizeof(name), "legs/leg_%03d_%03d", mission.sites[k].site,
                  mission.sites[k + 1].site);
    const fs::path leg = run_dir / name;
    std::ifstream unit_file(leg / "unit.json"), matches_file(leg / "matches.csv");
    if (!unit_file || !matches_file) {
      throw Error(leg.string() + ": no unit.json or matches.csv; run `areomap run` first");
    }
    const nlohmann::json summary =
        k < run_legs.size() ? run_legs[k] : nlohmann::json::parse(unit_file)["summary"];
    const nlohmann::json dropped = summary.value("leg_test", nlohmann::json::object())
                                       .value("dropped_ids", nlohmann::json::array());
    const bool leg_accepted = summary.value("outcome", std::string()) == "matched";
    std::string line, dropped_text;
    std::getline(matches_file, line);
    int matches = 0, correct = 0, seen_right = 0;
    while (std::getline(matches_file, line)) {
      const std::vector<std::string> f = SplitCsvLine(line);
      if (f.size() < 10) throw Error(leg.string() + "/matches.csv: short row '" + line + "'");
      const Eigen::Vector3d a(std::stod(f[2]), std::stod(f[3]), std::stod(f[4]));
      const Eigen::Vector3d b(std::stod(f[5]), std::stod(f[6]), std::stod(f[7]));
      const int rock_a = RockUnder(truth, (world_from_site[k] * a).head<2>(), std::stod(f[8]));
      const int rock_b = RockUnder(truth, (world_from_site[k + 1] * b).head<2>(), std::stod(f[9]));
      const bool right = rock_a >= 0 && rock_a == rock_b;
      const auto seen = [&](size_t site, const Eigen::Vector3d& peak, double sigma) {
        return sight.RockSeen(camera(site), world_from_site[site] * peak, sigma);
      };
      const int seen_a = seen(k, a, std::stod(f[8]));
      const bool seen_same = seen_a >= 0 && seen_a == seen(k + 1, b, std::stod(f[9]));
      ++matches;
      correct += right ? 1 : 0;
      seen_right += seen_same ? 1 : 0;
      bool was_dropped = false;
      for (const auto& id : dropped) {
        was_dropped |= bench::RockIdOfTie(id.get<std::string>()) == std::stoi(f[0]);
      }
      if (was_dropped) dropped_text += std::string(" r") + f[0] + (right ? " (right)" : " (wrong)");
      if (leg_accepted && !was_dropped) {
        ++accepted;
        accepted_correct += right ? 1 : 0;
        accepted_seen_right += seen_same ? 1 : 0;
      }
    }
    all += matches;
    all_correct += correct;
    all_seen_right += seen_right;
    legs_accepted += leg_accepted ? 1 : 0;
    const nlohmann::json prior = summary.value("prior", nlohmann::json::object());
    const double re = summary.value("relative_error_percent", std::nan(""));
    std::printf("%zu -> %zu  %-20s  %7d %7d %5d  %6.2f  %s%s\n", k, k + 1,
                prior.value("source", std::string("?")).c_str(), matches, correct, seen_right, re,
                summary.value("outcome", std::string("?")).c_str(),
                dropped_text.empty() ? "" : (": dropped" + dropped_text).c_str());
  }
  const auto percent = [](int n, int of) { return of > 0 ? 100.0 * n / of : 100.0; };
  std::printf(
      "all legs: %d matches, %d correct (precision %.1f %%); by the sight ray %d (%.1f %%)\n", all,
      all_correct, percent(all_correct, all), all_seen_right, percent(all_seen_right, all));
  std::printf(
      "legs accepted: %d of %zu; their tie points: %d, %d correct (precision %.1f %%); by the "
      "sight ray %d (%.1f %%)\n",
      legs_accepted, mission.sites.size() - 1, accepted, accepted_correct,
      percent(accepted_correct, accepted), accepted_seen_right,
      percent(accepted_seen_right, accepted));
  return 0;
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s MISSION_DIR RUN_DIR\n", argv[0]);
    return 2;
  }
  try {
    return areomap::Main(argv[1], argv[2]);
  } catch (const areomap::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
