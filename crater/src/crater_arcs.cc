#include "crater_arcs.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <unordered_map>
#include <utility>

#include <tbb/parallel_for.h>
#include <Eigen/Dense>

#include "edge_point.h"

namespace areomap::internal {
namespace {

constexpr int kSectors = 12;   // 30 degree normal-direction sectors
constexpr int kArcWindow = 3;  // sectors per arc window (90 degrees)
constexpr int kMinArcPoints = 5;

int SectorOf(const RimEdgePoint& p, bool signed_normals) {
  double angle = std::atan2(p.ny, p.nx);
  // Unsigned (a DTM crest's): the direction folded to [0, 180) degrees, spread over the circle.
  if (!signed_normals)
    angle = std::fmod(angle + 2.0 * std::numbers::pi, std::numbers::pi) * 2.0 - std::numbers::pi;
  const int s = static_cast<int>(
      std::floor((angle + std::numbers::pi) / (2.0 * std::numbers::pi) * kSectors));
  return std::clamp(s, 0, kSectors - 1);
}

std::optional<Arc> FitArc(const std::vector<RimEdgePoint>& points, const std::vector<int>& members,
                          double r_lo, double r_hi, const std::optional<Eigen::Vector2d>& sun) {
  Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
  for (int i : members) {
    const Eigen::Vector2d n = Normal(points[i]);
    const Eigen::Matrix2d projector = Eigen::Matrix2d::Identity() - n * n.transpose();
    a += projector;
    b += projector * Pos(points[i]);
  }
  const double count = static_cast<double>(members.size());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(a);
  if (eig.eigenvalues()(0) / count < 0.02) return std::nullopt;  // arc spans < ~40 degrees
  Arc arc;
  arc.center = a.ldlt().solve(b);
  double sum = 0.0, sum2 = 0.0, radial = 0.0;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (int i : members) {
    const Eigen::Vector2d d = Pos(points[i]) - arc.center;
    const double r = d.norm();
    sum += r;
    sum2 += r * r;
    radial += r > 0.0 ? Normal(points[i]).dot(d) / r : 0.0;
    mean += Pos(points[i]);
  }
  arc.radius = sum / count;
  const double spread = std::sqrt(std::max(0.0, sum2 / count - arc.radius * arc.radius));
  radial /= count;
  if (!InArcRadiusBand(arc.radius, r_lo, r_hi)) return std::nullopt;
  if (spread > 0.15 * arc.radius + 0.5 || std::abs(radial) < 0.8) return std::nullopt;
  arc.polarity = radial > 0.0 ? 1 : -1;
  if (sun) {
    const Eigen::Vector2d direction = (mean / count - arc.center).normalized();
    // A bowl's rim is brighter on the sunward side of the edge everywhere.
    if (arc.polarity * direction.dot(*sun) < -0.25) return std::nullopt;
  }
  arc.points = members;
  return arc;
}

// The arc-building edge points (those at least `min_strength` strong), compacted: their points,
// their indices among all edges, and their pixel rows as compressed rows (`row_start`, one
// entry per raster row + 1; `column` per point). Compact arrays keep the 12 flood fills below
// in cache: about half of the edges are weaker and never join an arc.
struct ArcEdges {
  std::vector<RimEdgePoint> points;
  std::vector<int> index;
  std::vector<int> row_start;
  std::vector<int> column;
};

ArcEdges SelectArcEdges(const RimEdges& edges, double min_strength) {
  ArcEdges out;
  out.row_start.assign(static_cast<size_t>(edges.rows) + 1, 0);
  for (int r = 0; r < edges.rows; ++r) {
    for (int i = edges.row_start[static_cast<size_t>(r)];
         i < edges.row_start[static_cast<size_t>(r) + 1]; ++i) {
      if (edges.points[static_cast<size_t>(i)].strength < min_strength) continue;
      out.points.push_back(edges.points[static_cast<size_t>(i)]);
      out.index.push_back(i);
      out.column.push_back(edges.column[static_cast<size_t>(i)]);
    }
    out.row_start[static_cast<size_t>(r) + 1] = static_cast<int>(out.points.size());
  }
  return out;
}

// 8-neighbour adjacency of the arc edges in compressed rows: the neighbours of point i are
// neighbours[offsets[i] .. offsets[i + 1]), in the order above row, left, right, below row.
// Built once, shared by the 12 direction windows.
struct EdgeAdjacency {
  std::vector<int> offsets;
  std::vector<int> neighbours;
};

EdgeAdjacency BuildAdjacency(const ArcEdges& edges) {
  const int n = static_cast<int>(edges.points.size());
  const int rows = static_cast<int>(edges.row_start.size()) - 1;
  EdgeAdjacency adjacency;
  adjacency.offsets.resize(static_cast<size_t>(n) + 1);
  adjacency.neighbours.reserve(static_cast<size_t>(n) * 2);
  // Points are in raster order: walking them, the candidates in the rows above and below
  // advance monotonically (one cursor each), the row's own neighbours are i - 1 and i + 1.
  const std::vector<int>& start = edges.row_start;
  const std::vector<int>& column = edges.column;
  int row = 0, above = 0, below = n > 0 ? start[1] : 0;
  for (int i = 0; i < n; ++i) {
    adjacency.offsets[static_cast<size_t>(i)] = static_cast<int>(adjacency.neighbours.size());
    if (start[static_cast<size_t>(row) + 1] <= i) {
      while (start[static_cast<size_t>(row) + 1] <= i) ++row;
      above = row > 0 ? start[static_cast<size_t>(row) - 1] : 0;
      below = start[static_cast<size_t>(row) + 1];
    }
    const int col = column[static_cast<size_t>(i)];
    const int row_begin = start[static_cast<size_t>(row)];
    const int row_end = start[static_cast<size_t>(row) + 1];
    const int below_end = row + 1 < rows ? start[static_cast<size_t>(row) + 2] : row_end;
    while (above < row_begin && column[static_cast<size_t>(above)] < col - 1) ++above;
    for (int j = above; j < row_begin && column[static_cast<size_t>(j)] <= col + 1; ++j)
      adjacency.neighbours.push_back(j);
    if (i > row_begin && column[static_cast<size_t>(i) - 1] == col - 1)
      adjacency.neighbours.push_back(i - 1);
    if (i + 1 < row_end && column[static_cast<size_t>(i) + 1] == col + 1)
      adjacency.neighbours.push_back(i + 1);
    while (below < below_end && column[static_cast<size_t>(below)] < col - 1) ++below;
    for (int j = below; j < below_end && column[static_cast<size_t>(j)] <= col + 1; ++j)
      adjacency.neighbours.push_back(j);
  }
  adjacency.offsets[static_cast<size_t>(n)] = static_cast<int>(adjacency.neighbours.size());
  return adjacency;
}

// Per edge: a bit for each of the kSectors direction windows holding its normal, and per
// window the edges in it in index order (the seed order).
struct DirectionWindows {
  std::vector<uint16_t> bits;
  std::vector<std::vector<int>> members_of;
};

DirectionWindows AssignDirectionWindows(const ArcEdges& edges, bool signed_normals) {
  const int n = static_cast<int>(edges.points.size());
  DirectionWindows out;
  out.bits.assign(static_cast<size_t>(n), 0);
  out.members_of.resize(kSectors);
  std::vector<uint16_t>& windows = out.bits;
  for (int i = 0; i < n; ++i) {
    const int s = SectorOf(edges.points[i], signed_normals);
    for (int k = 0; k < kArcWindow; ++k) {
      const int window = (s - k + kSectors) % kSectors;
      windows[i] = static_cast<uint16_t>(windows[i] | (1u << window));
    }
  }
  for (int i = 0; i < n; ++i) {
    for (uint16_t bits = windows[i]; bits != 0; bits = static_cast<uint16_t>(bits & (bits - 1))) {
      out.members_of[static_cast<size_t>(std::countr_zero(bits))].push_back(i);
    }
  }
  return out;
}

// One flood fill per window from each unvisited seed, seeds in index order. A task walks the
// edges once, band by band, for kWindowsPerTask adjacent windows (which share two thirds of
// their edges): the adjacency of a band stays in cache for all of them, where one pass per
// window streamed it from memory 12 times. Each window still takes its seeds in index order,
// so its arcs are the same as with one pass per window.
constexpr int kWindowsPerTask = 4;
static_assert(kSectors % kWindowsPerTask == 0, "every window belongs to one task");
constexpr int kBandEdges = 8192;

// What the flood fills of ExtractArcs read: the arc edges, their windows and adjacency, and
// the arcs' radius band and sun.
struct ArcSearch {
  const ArcEdges& edges;
  const DirectionWindows& windows;
  const EdgeAdjacency& adjacency;
  double r_lo = 0.0, r_hi = 0.0;
  const std::optional<Eigen::Vector2d>& sun;
};

// The edges 8-connected to `seed` whose normals lie in the window of `bit` and are not yet
// `seen` (marked now), in flood-fill order, into `members`; `stack` is working memory.
void WindowComponent(const ArcSearch& search, int seed, uint16_t bit, std::vector<char>& seen,
                     std::vector<int>& stack, std::vector<int>& members) {
  const EdgeAdjacency& adjacency = search.adjacency;
  const std::vector<uint16_t>& windows = search.windows.bits;
  members.clear();
  stack.assign(1, seed);
  seen[seed] = 1;
  while (!stack.empty()) {
    const int i = stack.back();
    stack.pop_back();
    members.push_back(i);
    const int* it = adjacency.neighbours.data() + adjacency.offsets[static_cast<size_t>(i)];
    const int* last = adjacency.neighbours.data() + adjacency.offsets[static_cast<size_t>(i) + 1];
    for (; it != last; ++it) {
      const int j = *it;
      if (seen[j] || !(windows[j] & bit)) continue;
      seen[j] = 1;
      stack.push_back(j);
    }
  }
}

// The arcs of the kWindowsPerTask windows of `task`, each window's into its slot of
// `per_window` (points as indices into all edges).
void ArcsOfWindowTask(const ArcSearch& search, int task,
                      std::vector<std::vector<Arc>>& per_window) {
  const int n = static_cast<int>(search.edges.points.size());
  std::array<std::vector<char>, kWindowsPerTask> visited;
  std::array<size_t, kWindowsPerTask> next_seed{};
  for (std::vector<char>& v : visited) v.assign(static_cast<size_t>(n), 0);
  std::vector<int> stack, members;
  for (int band_end = kBandEdges;; band_end += kBandEdges) {
    bool seeds_left = false;
    for (int k = 0; k < kWindowsPerTask; ++k) {
      const int window = task * kWindowsPerTask + k;
      const uint16_t bit = static_cast<uint16_t>(1u << window);
      const std::vector<int>& seeds = search.windows.members_of[static_cast<size_t>(window)];
      std::vector<char>& seen = visited[static_cast<size_t>(k)];
      size_t& next = next_seed[static_cast<size_t>(k)];
      for (; next < seeds.size() && seeds[next] < band_end; ++next) {
        if (seen[seeds[next]]) continue;
        WindowComponent(search, seeds[next], bit, seen, stack, members);
        if (static_cast<int>(members.size()) < kMinArcPoints) continue;
        if (auto arc = FitArc(search.edges.points, members, search.r_lo, search.r_hi, search.sun)) {
          for (int& i : arc->points) i = search.edges.index[static_cast<size_t>(i)];  // all_edges'
          per_window[static_cast<size_t>(window)].push_back(std::move(*arc));
        }
      }
      seeds_left |= next < seeds.size();
    }
    if (!seeds_left) break;
  }
}

}  // namespace

// The radii [level px] an arc may have when a level searches craters of radii [r_lo, r_hi]: an
// arc's circle comes from a part of the rim only.
bool InArcRadiusBand(double radius, double r_lo, double r_hi) {
  return radius >= 0.7 * r_lo && radius <= 1.3 * r_hi;
}

// The arcs of `arcs` in the radius band of [r_lo, r_hi], in their order.
std::vector<Arc> ArcsInRadiusBand(std::vector<Arc> arcs, double r_lo, double r_hi) {
  std::erase_if(arcs, [&](const Arc& arc) { return !InArcRadiusBand(arc.radius, r_lo, r_hi); });
  return arcs;
}

// Arcs from the edges at least `min_strength` strong (weaker edges still count as rim support
// when hypotheses are fitted, GatherSupport).
std::vector<Arc> ExtractArcs(const RimEdges& all_edges, double r_lo, double r_hi,
                             const std::optional<Eigen::Vector2d>& sun, double min_strength) {
  const ArcEdges edges = SelectArcEdges(all_edges, min_strength);
  const DirectionWindows windows = AssignDirectionWindows(edges, all_edges.signed_normals);
  const EdgeAdjacency adjacency = BuildAdjacency(edges);
  const ArcSearch search{edges, windows, adjacency, r_lo, r_hi, sun};
  std::vector<std::vector<Arc>> per_window(kSectors);
  tbb::parallel_for(0, kSectors / kWindowsPerTask,
                    [&](int task) { ArcsOfWindowTask(search, task, per_window); });
  std::vector<Arc> arcs;
  for (auto& w : per_window) {
    for (Arc& a : w) arcs.push_back(std::move(a));
  }
  return arcs;
}

// Groups arcs whose circles agree; each group lists arc indices, seeds first. With a sun, arcs
// of opposite polarity are also grouped when their centres are apart along the sun line by up
// to the seed's radius (+ 1.5 px) and agree across it: the two walls of a small bowl. Inside a
// bowl the shading's gradient runs along the sun line, and the smoothed gradient at each wall
// mixes it in, so each wall's normals meet off the true centre towards that wall (measured on
// 12-14 px bowls: about 0.4 r each, too far apart for the plain tolerance).
std::vector<std::vector<int>> GroupArcs(const std::vector<Arc>& arcs, double r_hi,
                                        const std::optional<Eigen::Vector2d>& sun) {
  std::vector<int> order(arcs.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
  std::sort(order.begin(), order.end(),
            [&](int x, int y) { return arcs[x].points.size() > arcs[y].points.size(); });
  const double cell = 0.35 * r_hi + 2.0;
  const auto key = [&](const Eigen::Vector2d& c) {
    const int64_t gx = static_cast<int64_t>(std::floor(c.x() / cell));
    const int64_t gy = static_cast<int64_t>(std::floor(c.y() / cell));
    return (gx << 32) ^ (gy & 0xffffffff);
  };
  std::unordered_map<int64_t, std::vector<int>> grid;
  for (size_t i = 0; i < arcs.size(); ++i) grid[key(arcs[i].center)].push_back(static_cast<int>(i));
  std::vector<char> used(arcs.size(), 0);
  std::vector<std::vector<int>> groups;
  for (int seed : order) {
    if (used[seed]) continue;
    const Arc& s = arcs[seed];
    std::vector<int> group{seed};
    used[seed] = 1;
    const double tolerance = 0.25 * s.radius + 1.5;
    const double along_sun = s.radius + 1.5;  // the other wall's arc: centre offset along
    const int reach = sun ? static_cast<int>(std::ceil(along_sun / cell)) : 1;
    const auto agrees = [&](const Arc& o) {
      const Eigen::Vector2d offset = o.center - s.center;
      if (offset.norm() <= tolerance) return true;
      if (!sun || o.polarity == s.polarity) return false;
      const double along = offset.dot(*sun);
      const double across = offset.x() * sun->y() - offset.y() * sun->x();
      return std::abs(along) <= along_sun && std::abs(across) <= tolerance;
    };
    for (int dx = -reach; dx <= reach; ++dx) {
      for (int dy = -reach; dy <= reach; ++dy) {
        const auto it = grid.find(key(s.center + Eigen::Vector2d(dx * cell, dy * cell)));
        if (it == grid.end()) continue;
        for (int j : it->second) {
          if (j == seed) continue;
          const Arc& o = arcs[j];
          if (!agrees(o)) continue;
          if (std::abs(o.radius / s.radius - 1.0) > 0.25) continue;
          group.push_back(j);
          used[j] = 1;
        }
      }
    }
    groups.push_back(std::move(group));
  }
  return groups;
}

}  // namespace areomap::internal
