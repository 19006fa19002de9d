// Truth of a generated mission for the rock benches (rock_legs_bench.cc, rock_funnel_bench.cc):
// the truth rocks and each site frame's true pose.
//
// Frames: each site frame is the rover's believed (level, north-up) frame (x north, y east,
// z down [m]), so a point of site k lies in site 0's frame at Rz(h_true - h_telemetry) p + T_true
// (truth/sites.csv, telemetry/). A peak belongs to the tallest truth rock whose footprint (base
// radius + 15 cm + half the peak's largest horizontal sigma, for the stereo range error) holds it.
// Failures: a missing or malformed truth file throws areomap::Error naming it.
#pragma once

#include <exception>
#include <fstream>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/rigid3d.h"

namespace areomap::bench {

struct TruthRock {
  int id = 0;
  Eigen::Vector2d north_east = Eigen::Vector2d::Zero();  // Site 0's frame [m].
  double height = 0.0;                                   // [m]
  double radius = 0.0;                                   // Semi-axis a [m].
  double ground_z = 0.0;  // Ground elevation under the centre [m above the ellipsoid].
};

// truth/rocks.csv: id, shape, east_m, north_m, ground_z_m, height_m, a_m, ...
inline std::vector<TruthRock> ReadTruthRocks(const std::filesystem::path& csv) {
  std::ifstream in(csv);
  if (!in) throw Error(csv.string() + ": cannot open the truth rocks");
  std::string line;
  std::getline(in, line);
  std::vector<TruthRock> rocks;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = SplitCsvLine(line);
    if (f.size() < 7) throw Error(csv.string() + ": expected 7+ fields in '" + line + "'");
    rocks.push_back({std::stoi(f[0]), Eigen::Vector2d(std::stod(f[3]), std::stod(f[2])),
                     std::stod(f[5]), std::stod(f[6]), std::stod(f[4])});
  }
  return rocks;
}

// Id of the tallest truth rock whose footprint (plus tolerance) holds `north_east`; -1 if none.
inline int RockUnder(const std::vector<TruthRock>& truth, const Eigen::Vector2d& north_east,
                     double sigma) {
  int best = -1;
  double height = 0.0;
  for (const TruthRock& r : truth) {
    if ((r.north_east - north_east).norm() <= r.radius + 0.15 + 0.5 * sigma && r.height > height) {
      height = r.height;
      best = r.id;
    }
  }
  return best;
}

// The truth rocks that could have made a peak, by its covariance rather than a disk: the peak's
// offset beyond the rock's footprint (base radius + 15 cm) has a Mahalanobis distance squared
// within 9.21 (2 dof, 99 %) under the peak's horizontal covariance `covariance` (plus (5 cm)^2),
// and the rock is at most 10 cm lower than the peak's measured height (heights are measured low;
// a noisy top rises a few cm at most). A far stereo peak is ~10x less certain along its line of
// sight than across it: the disk rule (RockUnder) calls a peak 1.4 sigma in front of its rock
// "not on it" and gives it to any low rock nearby. Ids, in no particular order.
inline std::vector<int> RocksThatCouldMake(const std::vector<TruthRock>& truth,
                                           const Eigen::Vector2d& north_east,
                                           const Eigen::Matrix2d& covariance,
                                           double measured_height) {
  const Eigen::Matrix2d inverse =
      (covariance + 0.05 * 0.05 * Eigen::Matrix2d::Identity()).inverse();
  std::vector<int> ids;
  for (const TruthRock& r : truth) {
    if (r.height < measured_height - 0.10) continue;
    const Eigen::Vector2d offset = r.north_east - north_east;
    const double norm = offset.norm();
    const double beyond = std::max(0.0, norm - r.radius - 0.15);
    if (beyond > 5.0) continue;
    const Eigen::Vector2d e = norm > 0.0 ? Eigen::Vector2d(offset * (beyond / norm)) : offset;
    if (e.dot(inverse * e) <= 9.21) ids.push_back(r.id);
  }
  return ids;
}

// Site 0's frame from each site frame (true pose, believed axes); throws without truth.
inline std::vector<Rigid3d> TrueWorldFromSites(const MissionManifest& mission) {
  if (mission.truth_sites.size() != mission.sites.size() || !mission.truth_rocks_csv) {
    throw Error(mission.root.string() + ": the mission has no truth (truth/sites.csv, rocks.csv)");
  }
  std::vector<Rigid3d> world_from_site;
  for (size_t k = 0; k < mission.sites.size(); ++k) {
    const double turn = mission.truth_sites[k].heading - mission.telemetry[k].heading;
    world_from_site.emplace_back(
        Eigen::Quaterniond(Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ())),
        mission.truth_sites[k].position);
  }
  return world_from_site;
}

// The site-a rock id of a rock tie point, from its id "sAAA-sBBB-r<id>" (MatchSitePair); -1 for
// an id of another form.
inline int RockIdOfTie(const std::string& tie_id) {
  const size_t at = tie_id.rfind("-r");
  if (at == std::string::npos || at + 2 >= tie_id.size()) return -1;
  try {
    return std::stoi(tie_id.substr(at + 2));
  } catch (const std::exception&) {
    return -1;
  }
}

}  // namespace areomap::bench
