#include "areomap/crater/crater_detector.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <unordered_map>
#include <utility>

#include <tbb/parallel_for.h>
#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/ellipse_fit.h"
#include "areomap/crater/shading_hypotheses.h"
#include "areomap/crater/upsample.h"
#include "areomap/map/error.h"
#include "bilinear_sample.h"
#include "detect_in_core.h"
#include "edge_scratch.h"
#include "ring_sampler.h"

namespace areomap {
namespace {

using internal::kRingSamples;
using internal::RingSampler;
using internal::RingStats;

constexpr double kPi = std::numbers::pi;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Radii [level px] searched at each pyramid level: level 0 from the minimum diameter, coarser
// levels from kCoarseMinRadius; consecutive levels overlap (16-20 px at level 0 = 8-10 at 1).
constexpr double kLevelMaxRadius = 20.0;
constexpr double kCoarseMinRadius = 8.0;
// The upsampled level (scale 0.5) searches up to this radius [its px]: 1 full-resolution px
// beyond kCoarseMinRadius, where the full-resolution level's radii begin.
constexpr double kUpsampledMaxRadius = 2.0 * kCoarseMinRadius + 2.0;
// The largest full-resolution arc [px] around which the upsampled level is searched: that
// level's largest radius, plus half a pixel for the arc's radius error.
constexpr double kSmallArcMaxRadius = 0.5 * kUpsampledMaxRadius + 0.5;
constexpr int kSectors = 12;   // 30 degree normal-direction sectors
constexpr int kArcWindow = 3;  // sectors per arc window (90 degrees)
constexpr int kMinArcPoints = 5;
constexpr int kCoverageBins = 36;
constexpr size_t kMaxFitPoints = 128;
// Arcs are built from edges at least this share of the rim strength threshold (min_edge_contrast
// x the high Canny threshold): a rim passing that threshold on average has most edges above half
// of it, while texture edges mostly stay below.
constexpr double kArcStrengthShare = 0.5;
// A group of arcs is rejected before any fit when its mean edge strength is below this share of
// the rim strength threshold (the fitted rim is checked at the full threshold); the upsampled
// level is searched around full-resolution edges this strong (UpsampledSearchRegions).
constexpr double kGroupStrengthShare = 0.8;
// Robust loop: reject when the first (most tolerant) support covers less than this share of
// min_coverage; stop refitting once centre and axes move less than kConvergedShift [px] together.
constexpr double kEarlyCoverageShare = 0.75;
constexpr double kConvergedShift = 0.05;
// Signature pre-screen of a hypothesis before its robust fit: fraction of the threshold.
constexpr double kPrescreenSlack = 0.5;

struct Level {
  cv::Mat image;  // CV_32F, NaN = nodata
  RimEdges edges;
  bool has_edges = false;  // edges are computed only for levels that are searched or refined on
  double scale = 1.0;      // one level px = `scale` full-resolution px (0.5: upsampled)
};

struct Arc {
  Eigen::Vector2d center;
  double radius = 0.0;
  int polarity = 0;  // +1: normals point out of the circle
  std::vector<int> points;
};

Eigen::Vector2d Pos(const RimEdgePoint& p) { return {p.x, p.y}; }
Eigen::Vector2d Normal(const RimEdgePoint& p) { return {p.nx, p.ny}; }

// Unit vector towards the sun in pixel coordinates (x right, y down), azimuth clockwise from up.
std::optional<Eigen::Vector2d> SunVector(const CraterDetectorOptions& o, RimSource source) {
  if (source != RimSource::kImage || !o.sun_azimuth_deg) return std::nullopt;
  const double az = *o.sun_azimuth_deg * kPi / 180.0;
  return Eigen::Vector2d(std::sin(az), -std::cos(az));
}

int SectorOf(const RimEdgePoint& p, bool signed_normals) {
  double angle = std::atan2(p.ny, p.nx);
  // Unsigned (a DTM crest's): the direction folded to [0, 180) degrees, spread over the circle.
  if (!signed_normals) angle = std::fmod(angle + 2.0 * kPi, kPi) * 2.0 - kPi;
  const int s = static_cast<int>(std::floor((angle + kPi) / (2.0 * kPi) * kSectors));
  return std::clamp(s, 0, kSectors - 1);
}

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

// Arcs from the edges at least `min_strength` strong (weaker edges still count as rim support
// when hypotheses are fitted, GatherSupport).
std::vector<Arc> ExtractArcs(const RimEdges& all_edges, double r_lo, double r_hi,
                             const std::optional<Eigen::Vector2d>& sun, double min_strength) {
  const ArcEdges edges = SelectArcEdges(all_edges, min_strength);
  const int n = static_cast<int>(edges.points.size());
  // Per edge: a bit for each of the kSectors direction windows holding its normal, and per
  // window the edges in it in index order (the seed order).
  std::vector<uint16_t> windows(static_cast<size_t>(n), 0);
  std::vector<std::vector<int>> members_of(kSectors);
  for (int i = 0; i < n; ++i) {
    const int s = SectorOf(edges.points[i], all_edges.signed_normals);
    for (int k = 0; k < kArcWindow; ++k) {
      const int window = (s - k + kSectors) % kSectors;
      windows[i] = static_cast<uint16_t>(windows[i] | (1u << window));
    }
  }
  for (int i = 0; i < n; ++i) {
    for (uint16_t bits = windows[i]; bits != 0; bits = static_cast<uint16_t>(bits & (bits - 1))) {
      members_of[static_cast<size_t>(std::countr_zero(bits))].push_back(i);
    }
  }
  const EdgeAdjacency adjacency = BuildAdjacency(edges);
  // One flood fill per window from each unvisited seed, seeds in index order. A task walks the
  // edges once, band by band, for kWindowsPerTask adjacent windows (which share two thirds of
  // their edges): the adjacency of a band stays in cache for all of them, where one pass per
  // window streamed it from memory 12 times. Each window still takes its seeds in index order,
  // so its arcs are the same as with one pass per window.
  constexpr int kWindowsPerTask = 4;
  static_assert(kSectors % kWindowsPerTask == 0, "every window belongs to one task");
  constexpr int kBandEdges = 8192;
  // The edges 8-connected to `seed` whose normals lie in the window of `bit` and are not yet
  // `seen` (marked now), in flood-fill order.
  const auto component = [&](int seed, uint16_t bit, std::vector<char>& seen,
                             std::vector<int>& stack, std::vector<int>& members) {
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
  };
  std::vector<std::vector<Arc>> per_window(kSectors);
  tbb::parallel_for(0, kSectors / kWindowsPerTask, [&](int task) {
    std::array<std::vector<char>, kWindowsPerTask> visited;
    std::array<size_t, kWindowsPerTask> next_seed{};
    for (std::vector<char>& v : visited) v.assign(static_cast<size_t>(n), 0);
    std::vector<int> stack, members;
    for (int band_end = kBandEdges;; band_end += kBandEdges) {
      bool seeds_left = false;
      for (int k = 0; k < kWindowsPerTask; ++k) {
        const int window = task * kWindowsPerTask + k;
        const uint16_t bit = static_cast<uint16_t>(1u << window);
        const std::vector<int>& seeds = members_of[static_cast<size_t>(window)];
        std::vector<char>& seen = visited[static_cast<size_t>(k)];
        size_t& next = next_seed[static_cast<size_t>(k)];
        for (; next < seeds.size() && seeds[next] < band_end; ++next) {
          if (seen[seeds[next]]) continue;
          component(seeds[next], bit, seen, stack, members);
          if (static_cast<int>(members.size()) < kMinArcPoints) continue;
          if (auto arc = FitArc(edges.points, members, r_lo, r_hi, sun)) {
            for (int& i : arc->points) i = edges.index[static_cast<size_t>(i)];  // all_edges'
            per_window[static_cast<size_t>(window)].push_back(std::move(*arc));
          }
        }
        seeds_left |= next < seeds.size();
      }
      if (!seeds_left) break;
    }
  });
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

// Edges within `tolerance` of the ellipse whose normals are aligned with its normal and, with a
// sun, whose polarity fits a bowl.
std::vector<Eigen::Vector2d> GatherSupport(const RimEdges& edges, const Ellipse& e,
                                           double tolerance,
                                           const std::optional<Eigen::Vector2d>& sun,
                                           double* mean_strength = nullptr) {
  double strength_sum = 0.0;
  std::vector<Eigen::Vector2d> support;
  const double reach = e.semi_major + tolerance + 1.0;
  const int c0 = std::max(0, static_cast<int>(std::floor(e.center.x() - reach)));
  const int c1 = std::min(edges.cols - 1, static_cast<int>(std::ceil(e.center.x() + reach)));
  const int r0 = std::max(0, static_cast<int>(std::floor(e.center.y() - reach)));
  const int r1 = std::min(edges.rows - 1, static_cast<int>(std::ceil(e.center.y() + reach)));
  const double cs = std::cos(e.angle), sn = std::sin(e.angle);
  const double a2 = e.semi_major * e.semi_major, b2 = e.semi_minor * e.semi_minor;
  // The distance test below is |p - c| |1 - 1/rho| = R |rho - 1| with R, the centre's distance
  // to the ellipse along the ray, at least the smaller semi-axis: points with rho outside
  // 1 -/+ tolerance / that axis fail it, and are skipped on rho^2 without square roots (the
  // axis shrunk by 1e-9 keeps rounding on the safe side).
  const double band = tolerance / (std::min(e.semi_major, e.semi_minor) * (1.0 - 1e-9));
  const double rho2_max = (1.0 + band) * (1.0 + band);
  const double rho2_min = band < 1.0 ? (1.0 - band) * (1.0 - band) : 0.0;
  for (int r = r0; r <= r1; ++r) {
    const int last = edges.row_start[static_cast<size_t>(r) + 1];
    for (int i = edges.FirstInRow(r, c0); i < last && edges.column[static_cast<size_t>(i)] <= c1;
         ++i) {
      const RimEdgePoint& p = edges.points[static_cast<size_t>(i)];
      const Eigen::Vector2d d = Pos(p) - e.center;
      const double u = cs * d.x() + sn * d.y(), v = -sn * d.x() + cs * d.y();
      const double rho2 = u * u / a2 + v * v / b2;
      if (rho2 > rho2_max || rho2 < rho2_min) continue;
      const double rho = std::sqrt(rho2);
      const double dist = d.norm();
      if (rho <= 1e-9 || std::abs(dist - dist / rho) > tolerance) continue;
      const Eigen::Vector2d g_local(u / a2, v / b2);
      const Eigen::Vector2d g =
          Eigen::Vector2d(cs * g_local.x() - sn * g_local.y(), sn * g_local.x() + cs * g_local.y())
              .normalized();
      const double alignment = Normal(p).dot(g);
      if (std::abs(alignment) < 0.8) continue;
      if (sun && (alignment > 0 ? 1.0 : -1.0) * (d / dist).dot(*sun) < -0.25) continue;
      support.push_back(Pos(p));
      strength_sum += p.strength;
    }
  }
  if (mean_strength) {
    *mean_strength = support.empty() ? 0.0 : strength_sum / static_cast<double>(support.size());
  }
  return support;
}

std::optional<Ellipse> SaneFit(const std::vector<Eigen::Vector2d>& points, const Ellipse& prior,
                               double max_axis_ratio) {
  const std::optional<Ellipse> fit = FitEllipseFast(points);
  if (!fit) return std::nullopt;
  const double r = prior.MeanRadius();
  if ((fit->center - prior.center).norm() > 0.35 * r + 1.0) return std::nullopt;
  if (std::abs(fit->MeanRadius() / r - 1.0) > 0.35) return std::nullopt;
  if (fit->semi_major > max_axis_ratio * fit->semi_minor) return std::nullopt;
  return fit;
}

// Image with sun: how well the interior's brightness follows a bowl lit from the sun side
// (far wall bright, near wall dark): Pearson correlation of the samples at elliptical radii
// 0.3-0.8 with -cos(angle to the sun), and the bright-dark contrast of the two walls over the
// surroundings' standard deviation. DTM: (mean rim height - mean interior height) / diameter.
struct SignatureValues {
  double value = kNaN;        // contrast (image) or depth ratio (DTM)
  double correlation = kNaN;  // image only
};

SignatureValues Signature(const cv::Mat& raster, RimSource source, const Ellipse& e,
                          const std::optional<Eigen::Vector2d>& sun) {
  constexpr int kSamples = kRingSamples;
  const RingSampler ring(e);
  SignatureValues out;
  if (source == RimSource::kImage) {
    if (!sun) return out;
    RingStats toward, away, outside;
    double sw = 0, sv = 0, sww = 0, svv = 0, swv = 0;
    int n = 0;
    for (double rho : {0.3, 0.45, 0.6, 0.75}) {
      for (int k = 0; k < kSamples; ++k) {
        const Eigen::Vector2d p = ring.Point(rho, k);
        const double w = (p - e.center).normalized().dot(*sun);
        const double v = internal::SampleBilinear(raster, p.x(), p.y());
        if (!std::isfinite(v)) continue;
        if (w > 0.3) toward.Add(v);
        if (w < -0.3) away.Add(v);
        sw += -w;
        sv += v;
        sww += w * w;
        svv += v * v;
        swv += -w * v;
        ++n;
      }
    }
    for (double rho : {1.3, 1.6, 1.9}) {
      for (int k = 0; k < kSamples; ++k) {
        const Eigen::Vector2d p = ring.Point(rho, k);
        outside.Add(internal::SampleBilinear(raster, p.x(), p.y()));
      }
    }
    const double scale = outside.n > 4 ? outside.Std() : kNaN;
    if (toward.n == 0 || away.n == 0 || !(scale > 0.0) || n < 8) return out;
    out.value = (away.Mean() - toward.Mean()) / scale;
    const double cov = swv / n - (sw / n) * (sv / n);
    const double var_w = sww / n - (sw / n) * (sw / n), var_v = svv / n - (sv / n) * (sv / n);
    out.correlation = var_w > 0 && var_v > 0 ? cov / std::sqrt(var_w * var_v) : kNaN;
    return out;
  }
  RingStats rim, inner;
  for (int k = 0; k < kSamples; ++k) {
    const Eigen::Vector2d p = ring.Point(1.0, k);
    rim.Add(internal::SampleBilinear(raster, p.x(), p.y()));
    for (double rho : {0.0, 0.25, 0.5}) {
      const Eigen::Vector2d q = ring.Point(rho, k);
      inner.Add(internal::SampleBilinear(raster, q.x(), q.y()));
    }
  }
  if (rim.n == 0 || inner.n == 0) return out;
  out.value = (rim.Mean() - inner.Mean()) / (2.0 * e.MeanRadius());
  return out;
}

// `slack` < 1 relaxes the threshold (a pre-screen on a rough ellipse).
bool SignaturePasses(const SignatureValues& s, RimSource source, const CraterDetectorOptions& o,
                     double slack = 1.0) {
  if (source == RimSource::kDtm) return s.value / o.dtm_posting >= slack * o.min_depth_ratio;
  if (!o.sun_azimuth_deg) return true;
  return s.value >= slack * o.min_shading_contrast;
}

// Fraction of 36 sectors of polar angle around the centre (in the ellipse's frame) holding a
// point: EdgeCoverage without the distance solves, for points already near the curve.
double AngularCoverage(const Ellipse& e, const std::vector<Eigen::Vector2d>& points) {
  std::array<bool, kCoverageBins> hit{};
  const double cs = std::cos(e.angle), sn = std::sin(e.angle);
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d d = p - e.center;
    const double u = (cs * d.x() + sn * d.y()) / e.semi_major;
    const double v = (-sn * d.x() + cs * d.y()) / e.semi_minor;
    const double t = std::atan2(v, u) + kPi;
    hit[static_cast<size_t>(std::clamp(static_cast<int>(t / (2.0 * kPi) * kCoverageBins), 0,
                                       kCoverageBins - 1))] = true;
  }
  return static_cast<double>(std::count(hit.begin(), hit.end(), true)) / kCoverageBins;
}

// RMS of the radial distances |p - c| (1 - 1/rho) to the ellipse: the orthogonal distance to
// first order for points near a near-circular rim.
double RadialRms(const Ellipse& e, const std::vector<Eigen::Vector2d>& points) {
  const double cs = std::cos(e.angle), sn = std::sin(e.angle);
  double sum = 0.0;
  for (const Eigen::Vector2d& p : points) {
    const Eigen::Vector2d d = p - e.center;
    const double u = (cs * d.x() + sn * d.y()) / e.semi_major;
    const double v = (-sn * d.x() + cs * d.y()) / e.semi_minor;
    const double rho = std::max(Eigen::Vector2d(u, v).norm(), 1e-12);  // not std::hypot: u, v ~ 1
    const double r = d.norm() * (1.0 - 1.0 / rho);
    sum += r * r;
  }
  return points.empty() ? kNaN : std::sqrt(sum / static_cast<double>(points.size()));
}

// Trimmed robust loop on `edges` from `start`, then the geometric fit and validation.
// With `geometric` false the trimmed direct fit is the result (no Ceres, sigmas NaN, residual
// from radial distances): the cheap form used to screen hypotheses.
std::optional<CraterDetection> FitAndValidate(const cv::Mat& raster, const RimEdges& edges,
                                              RimSource source, const Ellipse& start,
                                              const CraterDetectorOptions& o, bool geometric) {
  const std::optional<Eigen::Vector2d> sun = SunVector(o, source);
  Ellipse e = start;
  std::vector<Eigen::Vector2d> support;
  for (int iteration = 0; iteration < 3; ++iteration) {
    const double tolerance = std::max(1.5, (iteration == 0 ? 0.12 : 0.06) * e.MeanRadius());
    support = GatherSupport(edges, e, tolerance, sun);
    if (support.size() < 8) return std::nullopt;
    // Early rejection: the first gathering is the most tolerant one; a rim covering far fewer
    // sectors than required cannot pass the final coverage check on the tighter band.
    if (iteration == 0 && AngularCoverage(e, support) < kEarlyCoverageShare * o.min_coverage) {
      return std::nullopt;
    }
    const std::optional<Ellipse> fit = SaneFit(support, e, o.max_axis_ratio);
    if (!fit) break;
    const double moved = (fit->center - e.center).norm() +
                         std::abs(fit->semi_major - e.semi_major) +
                         std::abs(fit->semi_minor - e.semi_minor);
    e = *fit;
    if (moved < kConvergedShift) break;  // a refit would gather the same edges
  }
  double mean_strength = 0.0;
  support = GatherSupport(edges, e, std::max(1.5, 0.04 * e.MeanRadius()), sun, &mean_strength);
  if (support.size() < 8) return std::nullopt;
  // Cheap checks before the geometric fit: edge sharpness, bowl signature, sector coverage.
  const double edge_contrast =
      edges.high_threshold > 0.0 ? mean_strength / edges.high_threshold : 0.0;
  if (edge_contrast < o.min_edge_contrast) return std::nullopt;
  const SignatureValues direct_signature = Signature(raster, source, e, sun);
  if (!SignaturePasses(direct_signature, source, o)) return std::nullopt;
  const double direct_coverage = AngularCoverage(e, support);
  if (direct_coverage < o.min_coverage) return std::nullopt;
  CraterDetection d;
  if (geometric) {
    GeometricFitOptions fit_options;
    fit_options.loss = RobustLoss::kHuber;
    fit_options.loss_scale = 0.7;
    fit_options.max_num_iterations = 20;
    // The direct fit starts close. Stop at a relative cost change or step of 1e-7: a step of
    // 1e-7 x a tile coordinate (< 3e-4 px) is far below the edges' noise (~0.05 px on the
    // centre), and the fits end 1-2 iterations sooner than at 1e-10, with the same ellipses.
    fit_options.function_tolerance = 1e-7;
    fit_options.parameter_tolerance = 1e-7;
    // The geometric fit costs one distance solve per point and iteration: at most
    // kMaxFitPoints edges, evenly spread along the scan order (the direct fit used them all).
    std::vector<Eigen::Vector2d> fit_points;
    const size_t stride = (support.size() + kMaxFitPoints - 1) / kMaxFitPoints;
    for (size_t i = 0; i < support.size(); i += stride) fit_points.push_back(support[i]);
    const EllipseFitSummary summary = RefineEllipseGeometric(e, fit_points, fit_options);
    if (!summary.converged) return std::nullopt;
    d.ellipse = summary.ellipse;
    d.center_x_sigma = summary.center_x_sigma;
    d.center_y_sigma = summary.center_y_sigma;
    d.semi_major_sigma = summary.semi_major_sigma;
    d.semi_minor_sigma = summary.semi_minor_sigma;
    d.angle_sigma = summary.angle_sigma;
    d.rms_residual = summary.rms_residual;
    d.num_edge_points = summary.num_points;
  } else {
    d.ellipse = e;
    d.center_x_sigma = d.center_y_sigma = d.semi_major_sigma = d.semi_minor_sigma = d.angle_sigma =
        kNaN;
    d.rms_residual = RadialRms(e, support);
    d.num_edge_points = static_cast<int>(support.size());
  }
  const Ellipse& fitted = d.ellipse;
  if (fitted.semi_major > o.max_axis_ratio * fitted.semi_minor) return std::nullopt;
  if ((fitted.center - start.center).norm() > 0.4 * start.MeanRadius() + 1.0) return std::nullopt;
  d.edge_contrast = edge_contrast;
  d.efs = EllipseFitSimilarity(fitted, support);
  // Without the geometric fit the ellipse is the direct fit's: its values are known.
  d.coverage = geometric ? AngularCoverage(fitted, support) : direct_coverage;
  const SignatureValues signature =
      geometric ? Signature(raster, source, fitted, sun) : direct_signature;
  d.signature = signature.value;
  d.shading_correlation = signature.correlation;
  if (d.coverage < o.min_coverage) return std::nullopt;
  if (d.rms_residual > 0.08 * fitted.MeanRadius() + 0.6) return std::nullopt;
  double strength = 1.0;
  if (source == RimSource::kDtm) {
    const double depth_ratio = d.signature / o.dtm_posting;
    if (!(depth_ratio >= o.min_depth_ratio)) return std::nullopt;
    strength = std::min(1.0, depth_ratio / (3.0 * o.min_depth_ratio));
  } else if (sun) {
    if (!(d.signature >= o.min_shading_contrast)) return std::nullopt;
    strength = std::min(1.0, d.signature / (3.0 * o.min_shading_contrast));
  }
  const double fit_quality = std::exp(-d.rms_residual / (0.05 * fitted.MeanRadius() + 0.5));
  d.confidence = std::clamp(d.coverage * strength * fit_quality, 0.0, 1.0);
  const double reach = fitted.semi_major;
  d.partial = d.coverage < 0.6 || fitted.center.x() - reach < 0 || fitted.center.y() - reach < 0 ||
              fitted.center.x() + reach > raster.cols || fitted.center.y() + reach > raster.rows;
  return d;
}

RimEdges EdgesOf(const cv::Mat& raster, RimSource source, const CraterDetectorOptions& o,
                 double scale) {
  return source == RimSource::kImage ? DetectImageEdges(raster, o.edges)
                                     : DetectDtmCrests(raster, o.dtm_posting * scale, o.edges);
}

Ellipse Scaled(const Ellipse& e, double factor) {
  Ellipse s = e;
  s.center *= factor;
  s.semi_major *= factor;
  s.semi_minor *= factor;
  return s;
}

void Report(const ProgressCallback& progress, double fraction, std::string_view stage) {
  if (progress && !progress(fraction, stage)) throw Error("crater detection cancelled");
}

// Distance [px] from `p` to the rectangle `core` (0 inside); 0 without a core.
double DistanceOutside(const cv::Rect2d* core, const Eigen::Vector2d& p) {
  if (core == nullptr) return 0.0;
  const double dx = std::max({core->x - p.x(), 0.0, p.x() - (core->x + core->width)});
  const double dy = std::max({core->y - p.y(), 0.0, p.y() - (core->y + core->height)});
  return std::hypot(dx, dy);
}

// Where the upsampled level (scale 0.5) is worth searching: around each full-resolution arc
// whose circle is small enough for that level (radius <= kSmallArcMaxRadius) and whose edges are
// on average `min_strength` strong (as a group of arcs must be, kGroupStrengthShare). Each marks
// the 4 px blocks of a square of half-size 1.2 r + 2 px about the arc's centre (the rim, with room
// for the centre's and radius's errors; the windows add their margin); the result is rectangles of
// upsampled pixels inside `area`, one per run of marked blocks along a block row. Against round
// 10's rule (every block with >= 2 strong edge points, and its neighbours) the area of the bench's
// 10000^2 tile falls from 38 to 13 M upsampled px: the rims of larger craters and straight edges no
// longer count (docs/notes/benchmarks-history.md, round 12).
std::vector<cv::Rect> UpsampledSearchRegions(const std::vector<Arc>& full_resolution_arcs,
                                             const RimEdges& full_resolution, double min_strength,
                                             const cv::Rect& area) {
  constexpr int kBlock = 4;
  const int block_rows = (full_resolution.rows + kBlock - 1) / kBlock;
  const int block_cols = (full_resolution.cols + kBlock - 1) / kBlock;
  cv::Mat searched = cv::Mat::zeros(block_rows, block_cols, CV_8U);
  const auto mark = [&](const Eigen::Vector2d& center, double radius) {
    const double half = 1.2 * radius + 2.0;
    const auto block = [&](double v, int count) {
      return std::clamp(static_cast<int>(std::floor(v / kBlock)), 0, count - 1);
    };
    const int c0 = block(center.x() - half, block_cols), c1 = block(center.x() + half, block_cols);
    const int r0 = block(center.y() - half, block_rows), r1 = block(center.y() + half, block_rows);
    searched(cv::Range(r0, r1 + 1), cv::Range(c0, c1 + 1)).setTo(1);
  };
  for (const Arc& arc : full_resolution_arcs) {
    if (arc.radius > kSmallArcMaxRadius) continue;
    double strength = 0.0;
    for (int i : arc.points) strength += full_resolution.points[static_cast<size_t>(i)].strength;
    if (strength < min_strength * static_cast<double>(arc.points.size())) continue;
    mark(arc.center, arc.radius);
  }
  std::vector<cv::Rect> regions;
  const int step = 2 * kBlock;  // a block in upsampled pixels
  for (int r = 0; r < block_rows; ++r) {
    const uchar* row = searched.ptr<uchar>(r);
    for (int c = 0; c < block_cols;) {
      if (row[c] == 0) {
        ++c;
        continue;
      }
      const int begin = c;
      while (c < block_cols && row[c] != 0) ++c;
      const cv::Rect region = cv::Rect(begin * step, r * step, (c - begin) * step, step) & area;
      if (!region.empty()) regions.push_back(region);
    }
  }
  return regions;
}

// DetectCraters; with `core`, only craters centred in it (detect_in_core.h).
std::vector<CraterDetection> Detect(const cv::Mat& raster, RimSource source,
                                    const CraterDetectorOptions& o,
                                    const ProgressCallback& progress, const cv::Rect2d* core);

}  // namespace

bool CraterDetectorOptions::SearchesUpsampledLevel() const {
  return upsample_small_craters && 0.5 * min_diameter_px < kCoarseMinRadius;
}

void CraterDetectorOptions::Check() const {
  RequireOption(std::isfinite(min_diameter_px) && min_diameter_px >= kSmallestDiameterPx,
                "CraterDetectorOptions.min_diameter_px", ">= 4 px");
  RequireOption(max_diameter_px == 0.0 ||
                    (std::isfinite(max_diameter_px) && max_diameter_px >= min_diameter_px),
                "CraterDetectorOptions.max_diameter_px", "0 (no limit) or >= min_diameter_px");
  RequireOption(!sun_azimuth_deg || std::isfinite(*sun_azimuth_deg),
                "CraterDetectorOptions.sun_azimuth_deg", "a finite angle in degrees");
  edges.Check();
  RequireOption(min_coverage >= 0.0 && min_coverage <= 1.0, "CraterDetectorOptions.min_coverage",
                "in [0, 1]");
  RequireOption(std::isfinite(min_shading_contrast), "CraterDetectorOptions.min_shading_contrast",
                "finite");
  RequireOption(std::isfinite(min_depth_ratio), "CraterDetectorOptions.min_depth_ratio", "finite");
  RequireOption(std::isfinite(min_edge_contrast) && min_edge_contrast >= 0.0,
                "CraterDetectorOptions.min_edge_contrast", ">= 0");
  RequireOption(max_axis_ratio >= 1.0, "CraterDetectorOptions.max_axis_ratio", ">= 1");
  RequireOption(std::isfinite(dtm_posting) && dtm_posting > 0.0,
                "CraterDetectorOptions.dtm_posting", "> 0");
  RequireOption(tile_size >= 256, "CraterDetectorOptions.tile_size", ">= 256 px");
  RequireOption(tile_overlap >= 32 && tile_overlap <= tile_size,
                "CraterDetectorOptions.tile_overlap", "in [32, tile_size] px");
  shading_template.Check();
}

std::vector<CraterDetection> SuppressDuplicateCraters(std::vector<CraterDetection> detections) {
  std::stable_sort(detections.begin(), detections.end(),
                   [](const CraterDetection& a, const CraterDetection& b) {
                     return a.confidence > b.confidence;
                   });
  std::vector<CraterDetection> kept;
  for (const CraterDetection& d : detections) {
    const bool duplicate = std::any_of(kept.begin(), kept.end(), [&](const CraterDetection& k) {
      const double rd = d.ellipse.MeanRadius(), rk = k.ellipse.MeanRadius();
      const double distance = (d.ellipse.center - k.ellipse.center).norm();
      const double lo = std::min(rd, rk), hi = std::max(rd, rk);
      // The same rim, or a concentric inner edge (floor, shadow) of a more confident crater.
      return (distance < 0.5 * lo && hi < 1.3 * lo) || (distance < 0.5 * hi && hi < 1.6 * lo);
    });
    if (!duplicate) kept.push_back(d);
  }
  return kept;
}

std::optional<CraterDetection> RefineCrater(const cv::Mat& raster, RimSource source,
                                            const Ellipse& initial,
                                            const CraterDetectorOptions& options) {
  options.Check();
  cv::Mat f;
  raster.convertTo(f, CV_32F);
  return FitAndValidate(f, EdgesOf(f, source, options, 1), source, initial, options, true);
}

std::vector<CraterDetection> DetectCraters(const cv::Mat& raster, RimSource source,
                                           const CraterDetectorOptions& options,
                                           const ProgressCallback& progress) {
  return Detect(raster, source, options, progress, nullptr);
}

namespace internal {

CraterDetection ShiftedDetection(CraterDetection d, double dx, double dy, double factor) {
  d.ellipse.center = d.ellipse.center * factor + Eigen::Vector2d(dx, dy);
  d.ellipse.semi_major *= factor;
  d.ellipse.semi_minor *= factor;
  d.center_x_sigma *= factor;
  d.center_y_sigma *= factor;
  d.semi_major_sigma *= factor;
  d.semi_minor_sigma *= factor;
  d.rms_residual *= factor;
  return d;
}

std::vector<CraterDetection> DetectCratersInCore(const cv::Mat& raster, RimSource source,
                                                 const CraterDetectorOptions& options,
                                                 const cv::Rect2d& core) {
  std::vector<CraterDetection> kept;
  for (CraterDetection& d : Detect(raster, source, options, nullptr, &core)) {
    const Eigen::Vector2d& c = d.ellipse.center;
    if (c.x() >= core.x && c.x() < core.x + core.width && c.y() >= core.y &&
        c.y() < core.y + core.height) {
      kept.push_back(std::move(d));
    }
  }
  return kept;
}

}  // namespace internal

namespace {

std::vector<CraterDetection> Detect(const cv::Mat& raster, RimSource source,
                                    const CraterDetectorOptions& o,
                                    const ProgressCallback& progress, const cv::Rect2d* core) {
  o.Check();
  if (raster.channels() != 1) throw Error("crater detection: expected a single-band raster");
  if (raster.empty()) return {};
  const double max_radius =
      0.5 * (o.max_diameter_px > 0.0 ? o.max_diameter_px
                                     : static_cast<double>(std::max(raster.cols, raster.rows)));
  const double min_radius = 0.5 * o.min_diameter_px;
  std::vector<Level> levels;
  cv::Mat full;  // read only: shares a float input's pixels
  if (raster.depth() == CV_32F) {
    full = raster;
  } else {
    raster.convertTo(full, CV_32F);
  }
  // Small craters (radius < kCoarseMinRadius) are searched on a 2x upsampled copy, where their
  // rims hold four times the edge points; GDAL coordinates scale exactly by 2 under cv::resize.
  const bool upsample = o.SearchesUpsampledLevel();
  if (upsample) {
    Level up;
    up.scale = 0.5;
    // In the calling task's scratch when there is one: a fresh 4x tile-sized image would be
    // page-faulted in again for every tile (edge_scratch.h).
    if (internal::EdgeScratch* scratch = internal::CurrentEdgeScratch()) {
      up.image = scratch->Get(internal::EdgeScratch::kUpsampledImageSlot, full.rows * 2,
                              full.cols * 2, CV_32F);
    }
    UpsampleTwice(full, &up.image);  // cv::resize's values, written faster (upsample.h)
    levels.push_back(std::move(up));
  }
  const size_t base = levels.size();  // index of the full-resolution level
  levels.push_back({});
  levels.back().image = full;
  // The coarser levels one after the other in the calling task's scratch when there is one
  // (together less than a third of the full level's pixels): fresh images would be page-faulted
  // in again for every tile.
  float* pyramid_memory = nullptr;
  if (internal::EdgeScratch* scratch = internal::CurrentEdgeScratch()) {
    const int pixels = static_cast<int>(full.total() / 3 + 1);
    pyramid_memory =
        scratch->Get(internal::EdgeScratch::kPyramidSlot, 1, pixels, CV_32F).ptr<float>();
  }
  while (true) {
    const Level& last = levels.back();
    const double next_scale = last.scale * 2.0;
    if (kCoarseMinRadius * next_scale > max_radius * 1.25) break;
    if (std::min(last.image.cols, last.image.rows) / 2 < 3 * static_cast<int>(kCoarseMinRadius)) {
      break;
    }
    Level next;
    next.scale = next_scale;
    if (pyramid_memory != nullptr) {
      next.image = cv::Mat(last.image.rows / 2, last.image.cols / 2, CV_32F, pyramid_memory);
      pyramid_memory += next.image.total();
    }
    // 2x2 box averaging keeps the GDAL pixel grid: level coordinates x 2 = finer coordinates.
    // NaN holes stay NaN through the average.
    const cv::Mat& src = last.image;
    cv::Mat cropped = src(cv::Rect(0, 0, src.cols / 2 * 2, src.rows / 2 * 2));
    cv::resize(cropped, next.image, cv::Size(src.cols / 2, src.rows / 2), 0, 0, cv::INTER_AREA);
    levels.push_back(std::move(next));
  }
  const std::optional<Eigen::Vector2d> sun = SunVector(o, source);
  // Radii [level px] searched on level `li`, as {r_lo, r_hi}; none when r_hi < 0.8 r_lo.
  const auto radius_band = [&](size_t li) {
    const double scale = levels[li].scale;
    double r_lo = std::max(li == 0 ? 0.0 : kCoarseMinRadius, min_radius / scale);
    double r_hi = std::min(kLevelMaxRadius, max_radius / scale * 1.1);
    if (upsample && li == 0) r_hi = std::min(r_hi, kUpsampledMaxRadius);
    if (upsample && li == base) r_lo = kCoarseMinRadius - 1.0;
    return std::pair{r_lo, r_hi};
  };
  // The full-resolution level's arcs when they were found before the level's turn below.
  std::optional<std::vector<Arc>> full_resolution_arcs;
  if (upsample && o.upsample_only_around_small_arcs && source == RimSource::kImage) {
    // The full-resolution edges and arcs first (searched anyway), to choose where the upsampled
    // level's edges are needed. After the pyramid is built: growing `levels` copies its Levels
    // (cv::Mat's move is not noexcept), edges included.
    Level& full_level = levels[base];
    full_level.edges = EdgesOf(full_level.image, source, o, full_level.scale);
    full_level.has_edges = true;
    // Down to the smallest radius asked for: the level's own band is taken out of them below.
    const auto [r_lo, r_hi] = radius_band(base);
    full_resolution_arcs =
        ExtractArcs(full_level.edges, std::min(r_lo, min_radius), r_hi, sun,
                    kArcStrengthShare * o.min_edge_contrast * full_level.edges.high_threshold);
    Level& up = levels.front();
    const double strong =
        kGroupStrengthShare * o.min_edge_contrast * full_level.edges.high_threshold;
    // In a tile, only where the rim of a crater that may end in the core can lie (RimReach of
    // the level's largest arc, 1.3 x its radius band; full-resolution px, then the level's).
    cv::Rect area(0, 0, up.image.cols, up.image.rows);
    if (core != nullptr) {
      const double reach = internal::RimReach(1.3 * kUpsampledMaxRadius * up.scale, up.scale);
      const cv::Rect2d around(core->x - reach, core->y - reach, core->width + 2.0 * reach,
                              core->height + 2.0 * reach);
      area &= cv::Rect(cv::Point(static_cast<int>(std::floor(around.x / up.scale)),
                                 static_cast<int>(std::floor(around.y / up.scale))),
                       cv::Point(static_cast<int>(std::ceil(around.br().x / up.scale)),
                                 static_cast<int>(std::ceil(around.br().y / up.scale))));
    }
    up.edges = DetectImageEdgesInRegions(
        up.image, UpsampledSearchRegions(*full_resolution_arcs, full_level.edges, strong, area),
        o.edges);
    up.has_edges = true;
  }
  // Bowl-shading template hypotheses (shading_hypotheses.h), tried on their level below.
  std::vector<ShadingHypothesis> shading;
  if (sun && o.shading_template.enabled) {
    shading =
        FindShadingHypotheses(full, *o.sun_azimuth_deg, min_radius, max_radius, o.shading_template);
  }
  std::vector<char> shading_tried(shading.size(), 0);
  // Phase 1: screen hypotheses on every level with the cheap direct fit.
  std::vector<CraterDetection> candidates;
  for (size_t li = 0; li < levels.size(); ++li) {
    Level& level = levels[li];
    // Plain variables, not a structured binding: the lambdas below capture them (clang < 16).
    const std::pair<double, double> band = radius_band(li);
    const double r_lo = band.first, r_hi = band.second;
    if (r_hi < r_lo * 0.8) continue;  // no crater of the asked sizes at this level
    if (!level.has_edges) {
      level.edges = EdgesOf(level.image, source, o, level.scale);
      level.has_edges = true;
    }
    const std::vector<Arc> arcs =
        li == base && full_resolution_arcs
            ? ArcsInRadiusBand(std::move(*full_resolution_arcs), r_lo, r_hi)
            : ExtractArcs(level.edges, r_lo, r_hi, sun,
                          kArcStrengthShare * o.min_edge_contrast * level.edges.high_threshold);
    const std::vector<std::vector<int>> groups = GroupArcs(arcs, r_hi, sun);
    std::vector<std::optional<CraterDetection>> found(groups.size());
    tbb::parallel_for(size_t{0}, groups.size(), [&](size_t g) {
      const Arc& seed = arcs[groups[g][0]];
      if (DistanceOutside(core, seed.center * level.scale) >
          internal::CoreMargin(seed.radius * level.scale, level.scale)) {
        return;  // cannot end in the core
      }
      std::vector<int> indices;
      for (int a : groups[g])
        indices.insert(indices.end(), arcs[a].points.begin(), arcs[a].points.end());
      std::sort(indices.begin(), indices.end());
      indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
      double strength = 0.0;
      for (int i : indices) strength += level.edges.points[i].strength;
      // Cheap rejection before any fit: texture edges are weak (the rim's full support is
      // checked again after fitting).
      if (strength / static_cast<double>(indices.size()) <
          kGroupStrengthShare * o.min_edge_contrast * level.edges.high_threshold) {
        return;
      }
      std::vector<Eigen::Vector2d> points;
      points.reserve(indices.size());
      for (int i : indices) points.push_back(Pos(level.edges.points[i]));
      const Ellipse circle{seed.center, seed.radius, seed.radius, 0.0};
      Ellipse start = circle;
      if (points.size() >= 12) {
        if (auto fit = SaneFit(points, circle, o.max_axis_ratio)) start = *fit;
      }
      // Cheap rejection before the robust loop: the bowl signature of the rough ellipse, with
      // slack for its error (the fitted rim is checked at the full threshold).
      if (!SignaturePasses(Signature(level.image, source, start, sun), source, o,
                           kPrescreenSlack)) {
        return;
      }
      std::optional<CraterDetection> d =
          FitAndValidate(level.image, level.edges, source, start, o, false);
      if (!d) return;
      const double r = d->ellipse.MeanRadius();
      if (r < 0.8 * r_lo || r > 1.25 * r_hi) return;
      d->pyramid_level = static_cast<int>(li);
      // Candidates are compared across levels: keep them in full-resolution pixels.
      d->ellipse = Scaled(d->ellipse, level.scale);
      found[g] = d;
    });
    for (auto& d : found) {
      if (d) candidates.push_back(*d);
    }
    // Shading hypotheses of this level's sizes as starts of the same edge fit and validation.
    std::vector<std::optional<CraterDetection>> from_shading(shading.size());
    tbb::parallel_for(size_t{0}, shading.size(), [&](size_t h) {
      const double r = shading[h].radius / level.scale;
      if (shading_tried[h] || r < r_lo || r > r_hi) return;
      shading_tried[h] = 1;
      if (DistanceOutside(core, shading[h].center) >
          internal::CoreMargin(shading[h].radius, level.scale)) {
        return;
      }
      const Ellipse start =
          Scaled({shading[h].center, shading[h].radius, shading[h].radius, 0.0}, 1.0 / level.scale);
      from_shading[h] = FitAndValidate(level.image, level.edges, source, start, o, false);
      if (!from_shading[h]) return;
      from_shading[h]->pyramid_level = static_cast<int>(li);
      from_shading[h]->ellipse = Scaled(from_shading[h]->ellipse, level.scale);
    });
    for (auto& d : from_shading) {
      if (d) candidates.push_back(*d);
    }
    Report(progress, static_cast<double>(li + 1) / static_cast<double>(levels.size()),
           "craters: pyramid level");
  }
  // Phase 2: one geometric fit per distinct crater, on the finest level, the coarse fit refined
  // down the pyramid on the way.
  candidates = SuppressDuplicateCraters(std::move(candidates));
  // The refinement walks down from a candidate's level to full resolution: edges of the finer
  // levels that phase 1 skipped (sizes outside their search range) are needed now.
  int coarsest = -1;
  for (const CraterDetection& c : candidates) coarsest = std::max(coarsest, c.pyramid_level);
  if (!o.refine_to_full_resolution) coarsest = -1;
  for (int k = static_cast<int>(base); k < coarsest; ++k) {
    Level& level = levels[static_cast<size_t>(k)];
    if (!level.has_edges) {
      level.edges = EdgesOf(level.image, source, o, level.scale);
      level.has_edges = true;
    }
  }
  std::vector<std::optional<CraterDetection>> final_fits(candidates.size());
  tbb::parallel_for(size_t{0}, candidates.size(), [&](size_t i) {
    const CraterDetection& c = candidates[i];
    if (DistanceOutside(core, c.ellipse.center) >
        internal::CoreMargin(c.ellipse.MeanRadius(),
                             levels[static_cast<size_t>(c.pyramid_level)].scale)) {
      return;
    }
    int k = c.pyramid_level;
    Ellipse e = Scaled(c.ellipse, 1.0 / levels[static_cast<size_t>(k)].scale);
    const int finest = o.refine_to_full_resolution ? static_cast<int>(base) : k;
    while (k > finest) {
      const Level& finer = levels[static_cast<size_t>(k - 1)];
      const auto refined =
          FitAndValidate(finer.image, finer.edges, source, Scaled(e, 2.0), o, k - 1 == finest);
      if (!refined) break;
      e = refined->ellipse;
      --k;
      if (k == finest) final_fits[i] = refined;
    }
    if (k > finest || c.pyramid_level <= finest) {
      // Geometric fit on the finest level that still validates, scaled to full resolution.
      const Level& level = levels[static_cast<size_t>(k)];
      auto fit = FitAndValidate(level.image, level.edges, source, e, o, true);
      if (!fit) return;
      const double f = level.scale;
      fit->ellipse = Scaled(fit->ellipse, f);
      fit->center_x_sigma *= f;
      fit->center_y_sigma *= f;
      fit->semi_major_sigma *= f;
      fit->semi_minor_sigma *= f;
      fit->rms_residual *= f;
      final_fits[i] = fit;
    }
    if (final_fits[i]) {
      final_fits[i]->pyramid_level = c.pyramid_level - static_cast<int>(base);
      final_fits[i]->confidence = std::max(final_fits[i]->confidence, c.confidence);
    }
  });
  std::vector<CraterDetection> all;
  for (const auto& d : final_fits) {
    if (d && d->Diameter() >= o.min_diameter_px * 0.9 &&
        (o.max_diameter_px <= 0.0 || d->Diameter() <= o.max_diameter_px * 1.1)) {
      all.push_back(*d);
    }
  }
  if (!shading.empty()) {
    // Template-only craters where the edge pipeline found none.
    Level& level = levels[base];
    if (!level.has_edges) level.edges = EdgesOf(level.image, source, o, level.scale);
    all = SuppressDuplicateCraters(std::move(all));
    for (const CraterDetection& d : AcceptShadingHypotheses(
             full, level.edges, shading, all, *o.sun_azimuth_deg, o.shading_template)) {
      if (d.Diameter() >= o.min_diameter_px * 0.9) all.push_back(d);
    }
  }
  return KeepWithinDiameterLimits(SuppressDuplicateCraters(std::move(all)), o);
}

}  // namespace

std::vector<CraterDetection> KeepWithinDiameterLimits(std::vector<CraterDetection> detections,
                                                      const CraterDetectorOptions& options) {
  std::erase_if(detections, [&](const CraterDetection& d) {
    return d.Diameter() < options.min_diameter_px ||
           (options.max_diameter_px > 0.0 && d.Diameter() > options.max_diameter_px);
  });
  return detections;
}

}  // namespace areomap
