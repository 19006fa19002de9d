// A simulated bundle-adjustment network with known truth, for tests and benches: the generator's
// traverse (PlanTraverse: true and dead-reckoned site poses) plus tie points and control points
// drawn from ground landmarks with the noise their covariances claim (honest covariances).
//
// Frames: the traverse frame is site 0's site frame (x north, y east, z down, origin on the
// ground at site 0). Each site frame is the one the rover believed: level, origin on the ground at
// the site, but rotated about the vertical by the telemetry heading error e_k, so the true
// traverse_from_site is (Rz(-e_k), true position). Terrain heights come from a smooth analytic
// surface (no rendering, fast).
#pragma once

#include <cstdint>
#include <vector>

#include "areomap/adjustment/bundle_adjustment.h"
#include "areomap/map/stereo_error.h"
#include "areomap/samples/mission.h"

namespace areomap::testing {

struct SimulatedNetworkOptions {
  TraverseOptions traverse = MissionOptions::Preset("long").traverse;
  TelemetryErrorModel telemetry = MissionOptions::Preset("long").telemetry;
  double half_extent_m = 700.0;
  uint32_t seed = 1;
  // Tie points per leg, uniform within `tie_spread_m` of the leg's middle: "six to nine tie
  // points well distributed in the middle of the two sites" give ~1 % (ch. 4.1.1, Table 4.1).
  int tie_points_per_leg = 8;
  double tie_spread_m = 12.0;
  double min_range_m = 4.0;   // Landmark range from either site [m].
  double max_range_m = 25.0;  // Table 4.5 keeps Navcam points within ~25-30 m.
  int control_points_per_site = 0;
  double control_sigma_horizontal_m = 0.25;  // Orbital control, 1 sigma, per horizontal axis.
  double control_sigma_vertical_m = 0.5;
  double height_sigma_m = 0.0;
  // Tie points also as Navcam pixels (10-pair panorama, 25 deg down, CAHVOR with the rover's
  // believed heading), which then replace the stereo points in the adjustment.
  bool pixel_observations = false;
  double pixel_sigma_px = 0.5;  // > 0: each site's height above the ellipsoid with this sigma.
  double mast_height_m = 1.5;
  StereoErrorModel stereo;
  std::vector<int> sites_without_links;  // No tie point or control point touches these.
};

struct SimulatedNetwork {
  BundleInput input;               // Telemetry initial poses, priors, tie and control points.
  std::vector<Rigid3d> truth;      // True traverse_from_site per site.
  std::vector<Rigid3d> telemetry;  // Dead-reckoned traverse_from_site per site.
  double length_m = 0.0;           // Horizontal traverse length [m].
};

SimulatedNetwork SimulateNetwork(const SimulatedNetworkOptions& options);

// The tie points, priors and control points of one site (links to earlier sites only), for
// feeding an IncrementalBundle site by site.
struct SiteLinks {
  std::vector<RelativePosePrior> priors;
  std::vector<TiePoint> tie_points;
  std::vector<ControlPoint> control_points;
};
SiteLinks LinksOfSite(const BundleInput& input, int site);

}  // namespace areomap::testing
