#include "areomap/crater/crater_detector.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include <tbb/parallel_for.h>
#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/same_crater.h"
#include "areomap/crater/shading_hypotheses.h"
#include "areomap/crater/upsample.h"
#include "areomap/map/error.h"
#include "areomap/map/report_progress.h"
#include "crater_arcs.h"
#include "detect_in_core.h"
#include "edge_point.h"
#include "edge_scratch.h"
#include "rim_fit.h"

namespace areomap {
namespace {

using internal::Arc;
using internal::ArcsInRadiusBand;
using internal::ExtractArcs;
using internal::FitAndValidate;
using internal::GroupArcs;
using internal::Pos;
using internal::SaneFit;
using internal::Signature;
using internal::SignaturePasses;
using internal::SunVector;

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
// Arcs are built from edges at least this share of the rim strength threshold (min_edge_contrast
// x the high Canny threshold): a rim passing that threshold on average has most edges above half
// of it, while texture edges mostly stay below.
constexpr double kArcStrengthShare = 0.5;
// A group of arcs is rejected before any fit when its mean edge strength is below this share of
// the rim strength threshold (the fitted rim is checked at the full threshold); the upsampled
// level is searched around full-resolution edges this strong (UpsampledSearchRegions).
constexpr double kGroupStrengthShare = 0.8;
// Signature pre-screen of a hypothesis before its robust fit: fraction of the threshold.
constexpr double kPrescreenSlack = 0.5;

struct Level {
  cv::Mat image;  // CV_32F, NaN = nodata
  RimEdges edges;
  bool has_edges = false;  // edges are computed only for levels that are searched or refined on
  double scale = 1.0;      // one level px = `scale` full-resolution px (0.5: upsampled)
};

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
// upsampled pixels inside `area`, one per run of marked blocks along a block row. Small arcs only,
// rather than every block with strong edges: the rims of larger craters and straight edges do
// not count (docs/notes/benchmarks-history.md, round 12).
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

// What every stage of one detection reads.
struct DetectionContext {
  RimSource source;
  const CraterDetectorOptions& o;
  const cv::Rect2d* core;  // craters centred in it only (detect_in_core.h); null: everywhere
  double min_radius = 0.0, max_radius = 0.0;  // searched [full-resolution px]
  std::optional<Eigen::Vector2d> sun;
};

DetectionContext MakeContext(const cv::Mat& raster, RimSource source,
                             const CraterDetectorOptions& o, const cv::Rect2d* core) {
  const double max_radius =
      0.5 * (o.max_diameter_px > 0.0 ? o.max_diameter_px
                                     : static_cast<double>(std::max(raster.cols, raster.rows)));
  const double min_radius = 0.5 * o.min_diameter_px;
  return {source, o, core, min_radius, max_radius, SunVector(o, source)};
}

// The raster as CV_32F; read only: shares a float input's pixels.
cv::Mat AsFloat(const cv::Mat& raster) {
  cv::Mat full;
  if (raster.depth() == CV_32F) {
    full = raster;
  } else {
    raster.convertTo(full, CV_32F);
  }
  return full;
}

// The levels searched: the 2x upsampled copy first when there is one, then full resolution
// (`base`), then 2x2-averaged levels while their radii are asked for.
struct Pyramid {
  std::vector<Level> levels;
  size_t base = 0;         // index of the full-resolution level
  bool upsampled = false;  // levels[0] is the 2x upsampled copy
};

// Small craters (radius < kCoarseMinRadius) are searched on a 2x upsampled copy, where their
// rims hold four times the edge points; GDAL coordinates scale exactly by 2 under cv::resize.
Level UpsampledLevel(const cv::Mat& full) {
  Level up;
  up.scale = 0.5;
  // In the calling task's scratch when there is one: a fresh 4x tile-sized image would be
  // page-faulted in again for every tile (edge_scratch.h).
  if (internal::EdgeScratch* scratch = internal::CurrentEdgeScratch()) {
    up.image = scratch->Get(internal::EdgeScratch::kUpsampledImageSlot, full.rows * 2,
                            full.cols * 2, CV_32F);
  }
  UpsampleTwice(full, &up.image);  // cv::resize's values, written faster (upsample.h)
  return up;
}

// Appends 2x2-averaged levels after the last one while their radii are asked for and they are
// large enough to search.
void AddCoarserLevels(double max_radius, std::vector<Level>* levels) {
  const cv::Mat& full = levels->back().image;
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
    const Level& last = levels->back();
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
    levels->push_back(std::move(next));
  }
}

Pyramid BuildPyramid(const cv::Mat& full, bool upsample, double max_radius) {
  Pyramid pyramid;
  pyramid.upsampled = upsample;
  if (upsample) pyramid.levels.push_back(UpsampledLevel(full));
  pyramid.base = pyramid.levels.size();
  pyramid.levels.push_back({});
  pyramid.levels.back().image = full;
  AddCoarserLevels(max_radius, &pyramid.levels);
  return pyramid;
}

// Radii [level px] searched on one level; none when r_hi < 0.8 r_lo.
struct RadiusBand {
  double r_lo = 0.0, r_hi = 0.0;
  bool Empty() const { return r_hi < r_lo * 0.8; }
};

RadiusBand LevelRadiusBand(const Pyramid& pyramid, size_t li, const DetectionContext& ctx) {
  const double scale = pyramid.levels[li].scale;
  double r_lo = std::max(li == 0 ? 0.0 : kCoarseMinRadius, ctx.min_radius / scale);
  double r_hi = std::min(kLevelMaxRadius, ctx.max_radius / scale * 1.1);
  if (pyramid.upsampled && li == 0) r_hi = std::min(r_hi, kUpsampledMaxRadius);
  if (pyramid.upsampled && li == pyramid.base) r_lo = kCoarseMinRadius - 1.0;
  return {r_lo, r_hi};
}

void EnsureEdges(Level* level, const DetectionContext& ctx) {
  if (!level->has_edges) {
    level->edges = EdgesOf(level->image, ctx.source, ctx.o, level->scale);
    level->has_edges = true;
  }
}

// The upsampled level searched only around small arcs: the full-resolution edges and arcs first
// (searched anyway), to choose where the upsampled level's edges are needed, then those edges.
// Returns the full-resolution arcs, for that level's turn in ScreenLevels.
std::vector<Arc> EdgesAroundSmallArcs(Pyramid* pyramid, const DetectionContext& ctx) {
  const CraterDetectorOptions& o = ctx.o;
  // After the pyramid is built: growing `levels` copies its Levels (cv::Mat's move is not
  // noexcept), edges included.
  Level& full_level = pyramid->levels[pyramid->base];
  full_level.edges = EdgesOf(full_level.image, ctx.source, o, full_level.scale);
  full_level.has_edges = true;
  // Down to the smallest radius asked for: the level's own band is taken out of them below.
  const RadiusBand band = LevelRadiusBand(*pyramid, pyramid->base, ctx);
  std::vector<Arc> full_resolution_arcs =
      ExtractArcs(full_level.edges, std::min(band.r_lo, ctx.min_radius), band.r_hi, ctx.sun,
                  kArcStrengthShare * o.min_edge_contrast * full_level.edges.high_threshold);
  Level& up = pyramid->levels.front();
  const double strong = kGroupStrengthShare * o.min_edge_contrast * full_level.edges.high_threshold;
  // In a tile, only where the rim of a crater that may end in the core can lie (RimReach of
  // the level's largest arc, 1.3 x its radius band; full-resolution px, then the level's).
  cv::Rect area(0, 0, up.image.cols, up.image.rows);
  if (ctx.core != nullptr) {
    const cv::Rect2d* core = ctx.core;
    const double reach = internal::RimReach(1.3 * kUpsampledMaxRadius * up.scale, up.scale);
    const cv::Rect2d around(core->x - reach, core->y - reach, core->width + 2.0 * reach,
                            core->height + 2.0 * reach);
    area &= cv::Rect(cv::Point(static_cast<int>(std::floor(around.x / up.scale)),
                               static_cast<int>(std::floor(around.y / up.scale))),
                     cv::Point(static_cast<int>(std::ceil(around.br().x / up.scale)),
                               static_cast<int>(std::ceil(around.br().y / up.scale))));
  }
  up.edges = DetectImageEdgesInRegions(
      up.image, UpsampledSearchRegions(full_resolution_arcs, full_level.edges, strong, area),
      o.edges);
  up.has_edges = true;
  return full_resolution_arcs;
}

// Bowl-shading template hypotheses (shading_hypotheses.h), tried on their level by
// ScreenLevels; none without a sun or with the templates off.
std::vector<ShadingHypothesis> ShadingStarts(const cv::Mat& full, const DetectionContext& ctx) {
  const CraterDetectorOptions& o = ctx.o;
  if (!ctx.sun || !o.shading_template.enabled) return {};
  return FindShadingHypotheses(full, *o.sun_azimuth_deg, ctx.min_radius, ctx.max_radius,
                               o.shading_template);
}

// One searched level of the pyramid, as the screening fits see it.
struct LevelSearch {
  const Level& level;
  size_t index = 0;  // in the pyramid
  RadiusBand band;
};

// The screened candidate of one group of arcs (`group`: indices into `arcs`, seed first), in
// full-resolution pixels; none when it is rejected.
std::optional<CraterDetection> ScreenArcGroup(const LevelSearch& search,
                                              const std::vector<Arc>& arcs,
                                              const std::vector<int>& group,
                                              const DetectionContext& ctx) {
  const Level& level = search.level;
  const CraterDetectorOptions& o = ctx.o;
  const Arc& seed = arcs[group[0]];
  if (DistanceOutside(ctx.core, seed.center * level.scale) >
      internal::CoreMargin(seed.radius * level.scale, level.scale)) {
    return std::nullopt;  // cannot end in the core
  }
  std::vector<int> indices;
  for (int a : group) indices.insert(indices.end(), arcs[a].points.begin(), arcs[a].points.end());
  std::sort(indices.begin(), indices.end());
  indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
  double strength = 0.0;
  for (int i : indices) strength += level.edges.points[i].strength;
  // Cheap rejection before any fit: texture edges are weak (the rim's full support is
  // checked again after fitting).
  if (strength / static_cast<double>(indices.size()) <
      kGroupStrengthShare * o.min_edge_contrast * level.edges.high_threshold) {
    return std::nullopt;
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
  if (!SignaturePasses(Signature(level.image, ctx.source, start, ctx.sun), ctx.source, o,
                       kPrescreenSlack)) {
    return std::nullopt;
  }
  std::optional<CraterDetection> d =
      FitAndValidate(level.image, level.edges, ctx.source, start, o, false);
  if (!d) return std::nullopt;
  const double r = d->ellipse.MeanRadius();
  if (r < 0.8 * search.band.r_lo || r > 1.25 * search.band.r_hi) return std::nullopt;
  d->pyramid_level = static_cast<int>(search.index);
  // Candidates are compared across levels: keep them in full-resolution pixels.
  d->ellipse = Scaled(d->ellipse, level.scale);
  return d;
}

// The screened candidate of a shading hypothesis as the start of the same edge fit and
// validation, in full-resolution pixels; none when it is rejected.
std::optional<CraterDetection> ScreenShadingHypothesis(const LevelSearch& search,
                                                       const ShadingHypothesis& h,
                                                       const DetectionContext& ctx) {
  const Level& level = search.level;
  if (DistanceOutside(ctx.core, h.center) > internal::CoreMargin(h.radius, level.scale)) {
    return std::nullopt;
  }
  const Ellipse start = Scaled({h.center, h.radius, h.radius, 0.0}, 1.0 / level.scale);
  std::optional<CraterDetection> d =
      FitAndValidate(level.image, level.edges, ctx.source, start, ctx.o, false);
  if (!d) return std::nullopt;
  d->pyramid_level = static_cast<int>(search.index);
  d->ellipse = Scaled(d->ellipse, level.scale);
  return d;
}

void AppendFound(std::vector<std::optional<CraterDetection>>&& found,
                 std::vector<CraterDetection>* candidates) {
  for (auto& d : found) {
    if (d) candidates->push_back(*d);
  }
}

// The candidates of one level: its arc groups, then the shading hypotheses of its sizes not
// yet tried on another level (marked in `shading_tried`).
void ScreenLevel(const LevelSearch& search, const std::vector<Arc>& arcs,
                 const std::vector<ShadingHypothesis>& shading, std::vector<char>* shading_tried,
                 const DetectionContext& ctx, std::vector<CraterDetection>* candidates) {
  const std::vector<std::vector<int>> groups = GroupArcs(arcs, search.band.r_hi, ctx.sun);
  std::vector<std::optional<CraterDetection>> found(groups.size());
  tbb::parallel_for(size_t{0}, groups.size(),
                    [&](size_t g) { found[g] = ScreenArcGroup(search, arcs, groups[g], ctx); });
  AppendFound(std::move(found), candidates);
  std::vector<std::optional<CraterDetection>> from_shading(shading.size());
  std::vector<char>& tried = *shading_tried;
  tbb::parallel_for(size_t{0}, shading.size(), [&](size_t h) {
    const double r = shading[h].radius / search.level.scale;
    if (tried[h] || r < search.band.r_lo || r > search.band.r_hi) return;
    tried[h] = 1;
    from_shading[h] = ScreenShadingHypothesis(search, shading[h], ctx);
  });
  AppendFound(std::move(from_shading), candidates);
}

// Phase 1: hypotheses screened on every level with the cheap direct fit; the candidates in
// full-resolution pixels, level by level. `full_resolution_arcs`: the full-resolution level's
// arcs when EdgesAroundSmallArcs found them already.
std::vector<CraterDetection> ScreenLevels(Pyramid* pyramid,
                                          std::optional<std::vector<Arc>> full_resolution_arcs,
                                          const std::vector<ShadingHypothesis>& shading,
                                          const DetectionContext& ctx,
                                          const ProgressCallback& progress) {
  std::vector<Level>& levels = pyramid->levels;
  std::vector<char> shading_tried(shading.size(), 0);
  std::vector<CraterDetection> candidates;
  for (size_t li = 0; li < levels.size(); ++li) {
    Level& level = levels[li];
    const RadiusBand band = LevelRadiusBand(*pyramid, li, ctx);
    if (band.Empty()) continue;  // no crater of the asked sizes at this level
    EnsureEdges(&level, ctx);
    const std::vector<Arc> arcs =
        li == pyramid->base && full_resolution_arcs
            ? ArcsInRadiusBand(std::move(*full_resolution_arcs), band.r_lo, band.r_hi)
            : ExtractArcs(level.edges, band.r_lo, band.r_hi, ctx.sun,
                          kArcStrengthShare * ctx.o.min_edge_contrast * level.edges.high_threshold);
    ScreenLevel({level, li, band}, arcs, shading, &shading_tried, ctx, &candidates);
    ReportProgress(progress, static_cast<double>(li + 1) / static_cast<double>(levels.size()),
                   "craters: pyramid level");
  }
  return candidates;
}

// The refinement walks down from a candidate's level to full resolution: edges of the finer
// levels that phase 1 skipped (sizes outside their search range) are needed now.
void EnsureRefinementEdges(const std::vector<CraterDetection>& candidates, Pyramid* pyramid,
                           const DetectionContext& ctx) {
  int coarsest = -1;
  for (const CraterDetection& c : candidates) coarsest = std::max(coarsest, c.pyramid_level);
  if (!ctx.o.refine_to_full_resolution) coarsest = -1;
  for (int k = static_cast<int>(pyramid->base); k < coarsest; ++k) {
    EnsureEdges(&pyramid->levels[static_cast<size_t>(k)], ctx);
  }
}

// The final fit of candidate `c`: the coarse fit refined down the pyramid, then the geometric
// fit on the finest level that still validates, scaled to full resolution. None when it fails.
std::optional<CraterDetection> RefineCandidate(const Pyramid& pyramid, const CraterDetection& c,
                                               const DetectionContext& ctx) {
  const std::vector<Level>& levels = pyramid.levels;
  const int base = static_cast<int>(pyramid.base);
  if (DistanceOutside(ctx.core, c.ellipse.center) >
      internal::CoreMargin(c.ellipse.MeanRadius(),
                           levels[static_cast<size_t>(c.pyramid_level)].scale)) {
    return std::nullopt;
  }
  std::optional<CraterDetection> result;
  int k = c.pyramid_level;
  Ellipse e = Scaled(c.ellipse, 1.0 / levels[static_cast<size_t>(k)].scale);
  const int finest = ctx.o.refine_to_full_resolution ? base : k;
  while (k > finest) {
    const Level& finer = levels[static_cast<size_t>(k - 1)];
    const auto refined = FitAndValidate(finer.image, finer.edges, ctx.source, Scaled(e, 2.0), ctx.o,
                                        k - 1 == finest);
    if (!refined) break;
    e = refined->ellipse;
    --k;
    if (k == finest) result = refined;
  }
  if (k > finest || c.pyramid_level <= finest) {
    // Geometric fit on the finest level that still validates, scaled to full resolution.
    const Level& level = levels[static_cast<size_t>(k)];
    auto fit = FitAndValidate(level.image, level.edges, ctx.source, e, ctx.o, true);
    if (!fit) return std::nullopt;
    const double f = level.scale;
    fit->ellipse = Scaled(fit->ellipse, f);
    fit->center_x_sigma *= f;
    fit->center_y_sigma *= f;
    fit->semi_major_sigma *= f;
    fit->semi_minor_sigma *= f;
    fit->rms_residual *= f;
    result = fit;
  }
  if (result) {
    result->pyramid_level = c.pyramid_level - base;
    result->confidence = std::max(result->confidence, c.confidence);
  }
  return result;
}

// Phase 2: one geometric fit per distinct crater, on the finest level, the coarse fit refined
// down the pyramid on the way; the fits within the asked diameters (with 10 % slack), in
// candidate order.
std::vector<CraterDetection> RefineCandidates(const std::vector<CraterDetection>& candidates,
                                              Pyramid* pyramid, const DetectionContext& ctx) {
  EnsureRefinementEdges(candidates, pyramid, ctx);
  std::vector<std::optional<CraterDetection>> final_fits(candidates.size());
  tbb::parallel_for(size_t{0}, candidates.size(), [&](size_t i) {
    final_fits[i] = RefineCandidate(*pyramid, candidates[i], ctx);
  });
  const CraterDetectorOptions& o = ctx.o;
  std::vector<CraterDetection> all;
  for (const auto& d : final_fits) {
    if (d && d->Diameter() >= o.min_diameter_px * 0.9 &&
        (o.max_diameter_px <= 0.0 || d->Diameter() <= o.max_diameter_px * 1.1)) {
      all.push_back(*d);
    }
  }
  return all;
}

// Template-only craters where the edge pipeline found none, appended to `all` (duplicates
// among `all` suppressed first).
void AddShadingOnlyCraters(const cv::Mat& full, const std::vector<ShadingHypothesis>& shading,
                           const DetectionContext& ctx, Pyramid* pyramid,
                           std::vector<CraterDetection>* all) {
  if (shading.empty()) return;
  const CraterDetectorOptions& o = ctx.o;
  Level& level = pyramid->levels[pyramid->base];
  EnsureEdges(&level, ctx);
  *all = SuppressDuplicateCraters(std::move(*all));
  for (const CraterDetection& d : AcceptShadingHypotheses(full, level.edges, shading, *all,
                                                          *o.sun_azimuth_deg, o.shading_template)) {
    if (d.Diameter() >= o.min_diameter_px * 0.9) all->push_back(d);
  }
}

// DetectCraters; with `core`, only craters centred in it (detect_in_core.h).
std::vector<CraterDetection> Detect(const cv::Mat& raster, RimSource source,
                                    const CraterDetectorOptions& o,
                                    const ProgressCallback& progress, const cv::Rect2d* core) {
  o.Check();
  if (raster.channels() != 1) throw Error("crater detection: expected a single-band raster");
  if (raster.empty()) return {};
  const DetectionContext ctx = MakeContext(raster, source, o, core);
  const cv::Mat full = AsFloat(raster);
  Pyramid pyramid = BuildPyramid(full, o.SearchesUpsampledLevel(), ctx.max_radius);
  std::optional<std::vector<Arc>> full_resolution_arcs;
  if (pyramid.upsampled && o.upsample_only_around_small_arcs && source == RimSource::kImage) {
    full_resolution_arcs = EdgesAroundSmallArcs(&pyramid, ctx);
  }
  const std::vector<ShadingHypothesis> shading = ShadingStarts(full, ctx);
  std::vector<CraterDetection> candidates =
      ScreenLevels(&pyramid, std::move(full_resolution_arcs), shading, ctx, progress);
  std::vector<CraterDetection> all =
      RefineCandidates(SuppressDuplicateCraters(std::move(candidates)), &pyramid, ctx);
  AddShadingOnlyCraters(full, shading, ctx, &pyramid, &all);
  return KeepWithinDiameterLimits(SuppressDuplicateCraters(std::move(all)), o);
}

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
      // The same rim, or a concentric inner edge (floor, shadow) of a more confident crater.
      return SameCraterOrConcentric({d.ellipse.center, 2.0 * d.ellipse.MeanRadius()},
                                    {k.ellipse.center, 2.0 * k.ellipse.MeanRadius()});
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

std::vector<CraterDetection> KeepWithinDiameterLimits(std::vector<CraterDetection> detections,
                                                      const CraterDetectorOptions& options) {
  std::erase_if(detections, [&](const CraterDetection& d) {
    return d.Diameter() < options.min_diameter_px ||
           (options.max_diameter_px > 0.0 && d.Diameter() > options.max_diameter_px);
  });
  return detections;
}

}  // namespace areomap
