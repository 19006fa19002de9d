#include "areomap/registration/rock_matching.h"

#include <cmath>
#include <cstdio>
#include <numbers>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/samples/simulated_points.h"

namespace areomap {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Scene RockyScene(uint32_t seed) {
  SceneOptions options;
  options.half_extent_m = 60.0;
  options.crater_count = 0;
  options.roughness_m = 0.3;
  options.rock_path = {Eigen::Vector2d(-30, 0), Eigen::Vector2d(30, 0)};
  options.rock_abundance_k = 0.08;
  options.rock_corridor_m = 15.0;
  options.seed = seed;
  return Scene(options);
}

struct SimulatedSite {
  Eigen::Vector2d enu;
  double ground = 0.0;
  SiteRocks rocks;
};

SimulatedSite MakeSite(const Scene& scene, const Eigen::Vector2d& enu, int id, double az_min,
                       double az_max, uint32_t seed) {
  SimulatedPointsOptions sim;
  sim.azimuth_min_deg = az_min;
  sim.azimuth_max_deg = az_max;
  sim.max_range_m = 20.0;
  sim.angular_step_rad = 2e-3;
  sim.seed = seed;
  const PointCloud cloud = SimulateSitePointCloud(scene, enu, id, sim);
  SimulatedSite site;
  site.enu = enu;
  site.ground = scene.GroundHeightAt(enu.x(), enu.y());
  site.rocks.site = id;
  site.rocks.camera_center = cloud.camera_center;
  site.rocks.rocks = ExtractRocks(cloud, {});
  return site;
}

// The true rock under a site-frame peak (nearest footprint within 0.5 m), or -1.
int TrueRock(const Scene& scene, const SimulatedSite& site, const Eigen::Vector3d& peak) {
  const Eigen::Vector2d enu = site.enu + Eigen::Vector2d(peak.y(), peak.x());
  int best = -1;
  double best_gap = 0.5;
  for (const Rock& r : scene.rocks()) {
    const double gap = (r.center - enu).norm() - r.a;
    if (gap < best_gap) {
      best_gap = gap;
      best = r.id;
    }
  }
  return best;
}

TEST(RockMatching, Explore) {
  const Scene scene = RockyScene(5);
  for (double distance : {10.0, 15.0, 20.0, 25.0}) {
    const Eigen::Vector2d enu_a(-distance / 2, 0.0), enu_b(distance / 2, 0.0);
    const SimulatedSite a = MakeSite(scene, enu_a, 1, 20, 160, 11);
    const SimulatedSite b = MakeSite(scene, enu_b, 2, 200, 340, 12);
    // Truth: site frames share their axes; b's origin in a.
    const Eigen::Vector3d truth(0.0, distance, -(b.ground - a.ground));
    // Telemetry-like prior: 1.5 degree heading error and ~3 % position error.
    const Rigid3d prior(Eigen::AngleAxisd(1.5 * kDeg, Eigen::Vector3d::UnitZ()).matrix(),
                        truth + Eigen::Vector3d(0.4, -0.3, 0.05));
    const SitePairMatch match = MatchSitePair(a.rocks, b.rocks, prior, {});
    int correct = 0;
    for (const RockMatch& m : match.matches) {
      const int ta = TrueRock(scene, a, a.rocks.rocks[m.rock_a].peak);
      const int tb = TrueRock(scene, b, b.rocks.rocks[m.rock_b].peak);
      correct += (ta >= 0 && ta == tb) ? 1 : 0;
      if (!(ta >= 0 && ta == tb)) {
        const Eigen::Vector3d& P = a.rocks.rocks[m.rock_a].peak;
        const Eigen::Vector3d& Q = b.rocks.rocks[m.rock_b].peak;
        const Eigen::Vector2d pe = a.enu + Eigen::Vector2d(P.y(), P.x());
        const Eigen::Vector2d qe = b.enu + Eigen::Vector2d(Q.y(), Q.x());
        const Rock* ra = nullptr; const Rock* rb = nullptr;
        for (const Rock& r : scene.rocks()) { if (r.id == ta) ra = &r; if (r.id == tb) rb = &r; }
        printf("  WRONG %d vs %d cost %.2f votes %d |P-Q| %.2f sigP %.2f sigQ %.2f rockdist %.2f Pc %.2f Qc %.2f\n", ta, tb, m.model_cost, m.pattern_count,
          (pe - qe).norm(), std::sqrt(a.rocks.rocks[m.rock_a].peak_covariance.topLeftCorner<2,2>().trace()),
          std::sqrt(b.rocks.rocks[m.rock_b].peak_covariance.topLeftCorner<2,2>().trace()),
          ra && rb ? (ra->center - rb->center).norm() : -1.0, ra ? (pe - ra->center).norm() : -1.0, rb ? (qe - rb->center).norm() : -1.0);
      }
    }
    printf("D %.0f rocks %zu/%zu eligible %d/%d significant %d model %d pattern %d matches %zu correct %d RE %.2f %s\n",
           distance, a.rocks.rocks.size(), b.rocks.rocks.size(), match.eligible_a, match.eligible_b,
           match.significant, match.model_matches, match.pattern_matches, match.matches.size(),
           correct, match.error ? match.error->relative_error_percent : -1.0,
           ToString(match.report.outcome).c_str());
  }
}

}  // namespace
}  // namespace areomap
