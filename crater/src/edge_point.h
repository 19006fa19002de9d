// A rim edge point's position and normal as Eigen vectors, internal to the crater module (the
// detector's arcs and rim fits read them). Frame: the edges' raster pixels (GDAL convention).
#pragma once

#include <Eigen/Core>

#include "areomap/crater/rim_edges.h"

namespace areomap::internal {

inline Eigen::Vector2d Pos(const RimEdgePoint& p) { return {p.x, p.y}; }
inline Eigen::Vector2d Normal(const RimEdgePoint& p) { return {p.nx, p.ny}; }

}  // namespace areomap::internal
