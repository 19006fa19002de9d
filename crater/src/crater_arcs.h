// Circular arcs of rim edges and their grouping into crater hypotheses, internal to the crater
// module (the edge detector's first stage, crater_detector.cc).
//
// An arc is an 8-connected run of edges whose normals lie within one 90 degree window and
// meet near one point: its circle (centre, radius) starts a hypothesis. Frame: the pixels of
// the level the edges come from (GDAL convention). Failure: none; edges that form no arc are
// left out.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "areomap/crater/rim_edges.h"

namespace areomap::internal {

struct Arc {
  Eigen::Vector2d center;
  double radius = 0.0;
  int polarity = 0;  // +1: normals point out of the circle
  std::vector<int> points;
};

// The radii [level px] an arc may have when a level searches craters of radii [r_lo, r_hi]: an
// arc's circle comes from a part of the rim only.
bool InArcRadiusBand(double radius, double r_lo, double r_hi);

// The arcs of `arcs` in the radius band of [r_lo, r_hi], in their order.
std::vector<Arc> ArcsInRadiusBand(std::vector<Arc> arcs, double r_lo, double r_hi);

// Arcs from the edges at least `min_strength` strong (weaker edges still count as rim support
// when hypotheses are fitted, GatherSupport). `sun`: unit vector towards the sun in pixel
// coordinates, for images with a known sun (arcs of the wrong shading polarity are dropped).
// Arc points are indices into `all_edges.points`.
std::vector<Arc> ExtractArcs(const RimEdges& all_edges, double r_lo, double r_hi,
                             const std::optional<Eigen::Vector2d>& sun, double min_strength);

// Groups arcs whose circles agree; each group lists arc indices, seeds first (crater_arcs.cc
// states the rule).
std::vector<std::vector<int>> GroupArcs(const std::vector<Arc>& arcs, double r_hi,
                                        const std::optional<Eigen::Vector2d>& sun);

}  // namespace areomap::internal
