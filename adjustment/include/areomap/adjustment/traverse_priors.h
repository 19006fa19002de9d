// Relative pose priors of a traverse from dead reckoning (telemetry or visual odometry), for the
// bundle adjustment: one prior per consecutive pair of sites.
//
// Frames: `traverse_from_site` are the dead-reckoned poses of each site frame in the traverse
// frame (site 0's frame; x north, y east, z down, metres). Each prior is site k's pose in site
// k-1's frame, with DeadReckoningCovariance (bundle_adjustment.h): leg-length error
// `scale_sigma` (relative), heading drift `heading_sigma_rad` per leg, plus `floor_sigmas`.
#pragma once

#include <vector>

#include "areomap/adjustment/bundle_adjustment.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

// The floor used when none is given: roll/pitch 1 mrad (inclinometers), yaw 0.1 mrad, 2 cm.
Vector6d DefaultDeadReckoningFloor();

// Throws areomap::Error for negative sigmas.
std::vector<RelativePosePrior> DeadReckonedPriors(
    const std::vector<Rigid3d>& traverse_from_site, double scale_sigma, double heading_sigma_rad,
    const Vector6d& floor_sigmas = DefaultDeadReckoningFloor(),
    const std::string& source = "telemetry");

}  // namespace areomap
