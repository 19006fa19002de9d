// Ground footprint of a camera: where the rays of the image border meet a flat, level ground.
//
// Frame: a level frame with z down (MER SITE_FRAME: x north, y east, z down) in which the model
// is given; `ground_z` is the ground's z [m]. Rays that miss the ground (at or above the
// horizon) or meet it farther than `max_range_m` are cut at `max_range_m` horizontally from the
// ray origin, so the footprint is a closed polygon (x, y) [m], in order around the image border.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "areomap/map/camera_models.h"

namespace areomap {

// Throws areomap::Error for non-positive sizes or range.
std::vector<Eigen::Vector2d> GroundFootprint(const CameraModel& model_in_level_frame,
                                             const Eigen::Vector2i& image_size, double ground_z,
                                             double max_range_m, int samples_per_edge = 32);

// Area [m^2] of a simple polygon (shoelace formula; absolute value).
double PolygonArea(const std::vector<Eigen::Vector2d>& polygon);

}  // namespace areomap
