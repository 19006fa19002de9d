// Line-of-sight check of a stereo cloud: drops the points that contradict what the same camera
// sees around them.
//
// Seen from one camera, a 2.5D scene (terrain and rocks, no overhangs) shows its points in an
// order: along one azimuth, a farther visible point is never seen lower (at a smaller elevation
// angle) than a nearer one, because the ray to it would pass under the nearer point, through the
// solid ground below it. A stereo mismatch breaks the order in one of two ways:
//  - buried: put much too far away along a steep ray, the point lies under the ground seen in
//    front of it. The rover's own deck and wheels (nearer than the disparity range searched, so
//    matched to something else) come back metres below the ground; so do mismatches in
//    textureless shadow.
//  - floating: put much too near along a shallow ray (e.g. a far building matched a few metres
//    away), the point hangs above the ground, which would hide the ground the camera sees
//    behind it.
//
// The test, per point P with horizontal distance rho from the camera, horizontal range sigma s
// (from its covariance) and elevation angle e (up positive): point Q lies surely behind P when
// rho_Q - range_sigmas x s_Q - min_gap_m > rho_P. Within P's azimuth sector, P is buried when, of
// the points it lies surely behind, at least max_fraction (and at least min_count) are seen
// higher than e_P + elevation_tolerance; P is floating when, of the points surely behind it that
// are not buried, at least max_fraction (and min_count) are seen lower than e_P -
// elevation_tolerance. A few mismatches do not condemn the good points around them; the whole
// ground does condemn one.
//
// Frame: the cloud's +z must point down (MER site, rover and local-level frames; the K10 TSAI
// world), camera_center the left camera centre. Points within 1 cm of the camera's vertical are
// kept (no azimuth). Metres, radians inside; the options take degrees.
//
// Failure: bad options throw areomap::Error naming the field. O(n log n), parallel over sectors.
#pragma once

#include <cstddef>
#include <vector>

#include "areomap/map/point_cloud.h"

namespace areomap {

struct LineOfSightOptions {
  double sector_deg = 0.25;              // azimuth sector width
  double elevation_tolerance_deg = 0.5;  // seen this much higher / lower to count
  double range_sigmas = 3.0;             // "surely behind": by this many horizontal range sigmas
  double min_gap_m = 0.05;               // ... plus this (rock faces, small undercuts)
  double max_fraction = 0.5;             // of the points surely behind / in front
  int min_count = 3;                     // and at least this many
  void Check() const;                    // throws areomap::Error naming the field
};

struct LineOfSightDrops {
  size_t buried = 0;    // under the ground seen in front of them
  size_t floating = 0;  // over the ground seen behind them
};

// Removes the conflicting points from `cloud`, keeping the others' order. `witnesses`: more
// points seen by the same camera (e.g. those beyond the range kept) that count as evidence
// against the cloud's points but are not judged themselves.
LineOfSightDrops DropLineOfSightConflicts(PointCloud* cloud, const LineOfSightOptions& options = {},
                                          const std::vector<StereoPoint>& witnesses = {});

}  // namespace areomap
