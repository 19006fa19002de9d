// Truth of a generated mission for the rock benches (rock_legs_bench.cc, rock_funnel_bench.cc):
// the truth rocks and each site frame's true pose.
//
// Frames: each site frame is the rover's believed (level, north-up) frame (x north, y east,
// z down [m]), so a point of site k lies in site 0's frame at Rz(h_true - h_telemetry) p + T_true
// (truth/sites.csv, telemetry/). A peak belongs to the tallest truth rock whose footprint (base
// radius + 15 cm + half the peak's largest horizontal sigma, for the stereo range error) holds it;
// or, decisively, the truth rock whose surface the camera's sight ray through the peak meets
// (SightRayTruth).
// Failures: a missing or malformed truth file throws areomap::Error naming it.
#pragma once

#include <algorithm>
#include <cmath>
#include <exception>
#include <fstream>
#include <numbers>
#include <string>
#include <unordered_map>
#include <vector>

#include <Eigen/Geometry>

#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/rigid3d.h"
#include "areomap/samples/scene.h"

namespace areomap::bench {

struct TruthRock {
  int id = 0;
  Eigen::Vector2d north_east = Eigen::Vector2d::Zero();  // Site 0's frame [m].
  double height = 0.0;                                   // [m]
  double radius = 0.0;                                   // Semi-axis a [m].
  double ground_z = 0.0;  // Ground elevation under the centre [m above the ellipsoid].
  Rock shape;             // The generator's rock (ENU: x east, y north), for its surface.
};

// truth/rocks.csv: id, shape, east_m, north_m, ground_z_m, height_m, a_m, b_m, azimuth_deg,
// tilt_x_deg, tilt_y_deg.
inline std::vector<TruthRock> ReadTruthRocks(const std::filesystem::path& csv) {
  std::ifstream in(csv);
  if (!in) throw Error(csv.string() + ": cannot open the truth rocks");
  std::string line;
  std::getline(in, line);
  std::vector<TruthRock> rocks;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = SplitCsvLine(line);
    if (f.size() < 11) throw Error(csv.string() + ": expected 11 fields in '" + line + "'");
    const double radian = std::numbers::pi / 180.0;
    Rock shape;
    shape.id = std::stoi(f[0]);
    shape.shape = RockShapeFromString(f[1]);
    shape.center = Eigen::Vector2d(std::stod(f[2]), std::stod(f[3]));
    shape.ground_z = std::stod(f[4]);
    shape.height = std::stod(f[5]);
    shape.a = std::stod(f[6]);
    shape.b = std::stod(f[7]);
    shape.azimuth = std::stod(f[8]) * radian;
    shape.tilt_x = std::stod(f[9]) * radian;
    shape.tilt_y = std::stod(f[10]) * radian;
    rocks.push_back({shape.id, Eigen::Vector2d(shape.center.y(), shape.center.x()), shape.height,
                     shape.a, shape.ground_z, shape});
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

// The truth rock a stereo peak was seen on, by its sight ray. Stereo displaces a point along its
// ray (range error, eq. 4.3) and barely across it, so the ray from the camera through a peak
// passes through or just over the rock that made it, wherever along the ray the peak landed.
// "Just over": the block matcher gives the background just above a rock's top the rock's
// disparity (foreground fattening, about half a block and more), so the highest point of a far
// rock lies a few pixels above it. The ray is marched in 1 cm steps over the peak's range +-
// (4 sigma + 30 cm), sigma being the peak's largest horizontal sigma (along its line of sight, at
// least 1 cm); at each step inside a rock's footprint the miss is
//   chi2 = (height of the ray above the rock's surface / s_v)^2 + (step - peak's range)^2 / sigma^2
// with s_v = 2 cm + 2 px x ifov x range. The rock with the least chi2 wins, when it is <= 9.21
// (99 %, 2 dof); otherwise -1 (a peak on the ground or on a rock the ray misses). The rock's
// base is its centre's ground, flat. Occlusion is not modelled: the peak was seen, so its ray
// passed over any nearer rock. Frames: world points are site 0's frame (x north, y east, z
// down [m]); `origin_height` is that frame's origin height above the ellipsoid [m].
class SightRayTruth {
 public:
  // `ifov_rad`: the camera's angle per pixel (Navcam's 12 um / 14.67 mm by default, the widest
  // of the generator's cameras).
  SightRayTruth(const std::vector<TruthRock>& truth, double origin_height,
                double ifov_rad = 12.0e-6 / 14.67e-3)
      : truth_(truth), origin_height_(origin_height), ifov_rad_(ifov_rad) {
    for (size_t i = 0; i < truth_.size(); ++i) {
      const Rock& r = truth_[i].shape;
      const double reach = r.FootprintRadius();
      for (long long x = Cell(r.center.x() - reach); x <= Cell(r.center.x() + reach); ++x) {
        for (long long y = Cell(r.center.y() - reach); y <= Cell(r.center.y() + reach); ++y) {
          cells_[Key(x, y)].push_back(static_cast<int>(i));
        }
      }
    }
  }

  // Id of the truth rock seen at `peak_world` from `camera_world`, -1 when none is within the
  // chi2 limit. `sigma_m` is the peak's largest horizontal sigma [m].
  int RockSeen(const Eigen::Vector3d& camera_world, const Eigen::Vector3d& peak_world,
               double sigma_m) const {
    const Eigen::Vector3d camera = Enu(camera_world), peak = Enu(peak_world);
    const double range = (peak - camera).norm();
    if (range <= 0.0) return -1;
    const Eigen::Vector3d direction = (peak - camera) / range;
    const double sigma = std::max(0.01, sigma_m);
    const double vertical_sigma = 0.02 + 2.0 * ifov_rad_ * range;
    const double reach = 4.0 * sigma + 0.3;
    int best = -1;
    double best_chi2 = 9.21;
    for (double t = std::max(0.0, range - reach); t <= range + reach; t += 0.01) {
      const Eigen::Vector3d x = camera + t * direction;
      const auto it = cells_.find(Key(Cell(x.x()), Cell(x.y())));
      if (it == cells_.end()) continue;
      const double along = (t - range) / sigma;
      if (along * along >= best_chi2) continue;
      for (int i : it->second) {
        const Rock& r = truth_[static_cast<size_t>(i)].shape;
        const double above = r.HeightAbove(x.head<2>());
        if (above <= 0.0) continue;
        const double miss = std::max(0.0, x.z() - r.ground_z - above) / vertical_sigma;
        const double chi2 = miss * miss + along * along;
        if (chi2 < best_chi2) {
          best_chi2 = chi2;
          best = r.id;
        }
      }
    }
    return best;
  }

 private:
  static long long Cell(double metres) { return static_cast<long long>(std::floor(metres)); }
  static long long Key(long long x, long long y) { return (x << 32) ^ (y & 0xffffffffLL); }
  // ENU (x east, y north, z up above the ellipsoid) from site 0's frame.
  Eigen::Vector3d Enu(const Eigen::Vector3d& world) const {
    return Eigen::Vector3d(world.y(), world.x(), origin_height_ - world.z());
  }

  const std::vector<TruthRock>& truth_;
  double origin_height_;
  double ifov_rad_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

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
