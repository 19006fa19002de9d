#include "areomap/crater/crater_raster.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <iterator>
#include <memory>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/learned_detector.h"
#include "areomap/map/error.h"
#include "areomap/map/report_progress.h"
#include "detect_in_core.h"
#include "edge_scratch.h"
#include "raster_levels.h"

namespace areomap {
namespace {

// The combined detector's two halves: the edge detector with every option, the network with
// its rim fits run as with --method learned, without the shading checks.
CraterDetectorOptions EdgeDetectorHalf(const CraterDetectorOptions& o) {
  CraterDetectorOptions edges = o;
  edges.method = CraterMethod::kEdges;
  return edges;
}

CraterDetectorOptions NetworkHalf(const CraterDetectorOptions& o) {
  CraterDetectorOptions learned = o;
  learned.method = CraterMethod::kLearned;
  learned.sun_azimuth_deg.reset();
  return learned;
}

// How a raster larger than one padded tile is searched: tiles for craters up to the overlap in
// diameter, kept where their centre is in the tile core, and a decimated overview for the larger
// ones.
struct TilePlan {
  int width = 0, height = 0;  // the raster [px]
  int padded = 0;             // a tile's side with its overlap on both sides [px]
  int tiles_x = 0, tiles_y = 0, tile_count = 0;
  double tile_max_diameter = 0.0;  // [px]
  CraterDetectorOptions tile_options;
  bool run_tiles = false;      // the tiles can hold craters of the asked sizes
  bool need_overview = false;  // craters beyond the tiles' largest are asked for
  // The overview, decimated so it fits one padded tile. Tile cores start at multiples of
  // tile_size, a multiple of the factor, so each tile fills its core's share of the overview
  // (2 x 2 box averages, as ReadDecimated) and the raster is read once.
  int factor = 1;
  bool overview_from_tiles = false;
};

TilePlan PlanTiles(int width, int height, const CraterDetectorOptions& o) {
  TilePlan plan;
  plan.width = width;
  plan.height = height;
  plan.padded = o.tile_size + 2 * o.tile_overlap;
  plan.tiles_x = (width + o.tile_size - 1) / o.tile_size;
  plan.tiles_y = (height + o.tile_size - 1) / o.tile_size;
  plan.tile_count = plan.tiles_x * plan.tiles_y;
  plan.tile_max_diameter = static_cast<double>(o.tile_overlap);
  plan.need_overview = o.max_diameter_px == 0.0 || o.max_diameter_px > plan.tile_max_diameter;
  plan.tile_options = o;
  plan.tile_options.max_diameter_px = o.max_diameter_px == 0.0
                                          ? plan.tile_max_diameter
                                          : std::min(o.max_diameter_px, plan.tile_max_diameter);
  plan.factor = DecimationFactor(width, height, plan.padded);
  plan.run_tiles = plan.tile_options.max_diameter_px >= o.min_diameter_px;
  plan.overview_from_tiles = plan.need_overview && plan.run_tiles && o.tile_size % plan.factor == 0;
  return plan;
}

// One tile's window: its core and the core with the overlap around it, clipped to the raster
// [raster px, [c0, c1) x [r0, r1)].
struct TileWindow {
  int core_c0 = 0, core_r0 = 0, core_c1 = 0, core_r1 = 0;
  int c0 = 0, r0 = 0, c1 = 0, r1 = 0;
};

TileWindow TileWindowOf(const TilePlan& plan, int t, const CraterDetectorOptions& o) {
  TileWindow w;
  const int tx = t % plan.tiles_x, ty = t / plan.tiles_x;
  w.core_c0 = tx * o.tile_size;
  w.core_r0 = ty * o.tile_size;
  w.core_c1 = std::min(plan.width, w.core_c0 + o.tile_size);
  w.core_r1 = std::min(plan.height, w.core_r0 + o.tile_size);
  w.c0 = std::max(0, w.core_c0 - o.tile_overlap);
  w.r0 = std::max(0, w.core_r0 - o.tile_overlap);
  w.c1 = std::min(plan.width, w.core_c1 + o.tile_overlap);
  w.r1 = std::min(plan.height, w.core_r1 + o.tile_overlap);
  return w;
}

// The tile's core's share of the overview: 2 x 2 box averages of its pixels (disjoint per tile).
void AddToOverview(const cv::Mat& tile, const TileWindow& w, int factor, cv::Mat* overview) {
  const int out_c0 = w.core_c0 / factor, out_r0 = w.core_r0 / factor;
  const int out_w = std::min(overview->cols, w.core_c1 / factor) - out_c0;
  const int out_h = std::min(overview->rows, w.core_r1 / factor) - out_r0;
  if (out_w > 0 && out_h > 0) {
    const cv::Mat core =
        tile(cv::Rect(w.core_c0 - w.c0, w.core_r0 - w.r0, out_w * factor, out_h * factor));
    cv::Mat small;
    cv::resize(core, small, cv::Size(out_w, out_h), 0, 0, cv::INTER_AREA);
    small.copyTo((*overview)(cv::Rect(out_c0, out_r0, out_w, out_h)));  // disjoint per tile
  }
}

// The craters centred in one tile's core, in raster pixels; the tile's share of `overview`
// when the plan fills it from the tiles.
std::vector<CraterDetection> DetectInTile(const TilePlan& plan, int t, RimSource source,
                                          const CraterDetectorOptions& o,
                                          const internal::RasterLevels& levels,
                                          internal::EdgeScratchPool* scratch_pool,
                                          cv::Mat* overview) {
  const TileWindow w = TileWindowOf(plan, t, o);
  std::unique_ptr<internal::EdgeScratch> scratch = scratch_pool->Acquire();
  cv::Mat tile = scratch->Get(internal::EdgeScratch::kTileSlot, w.r1 - w.r0, w.c1 - w.c0, CV_32F,
                              static_cast<size_t>(plan.padded) * plan.padded);
  levels.ReadInto(0, cv::Rect(w.c0, w.r0, w.c1 - w.c0, w.r1 - w.r0), &tile);
  if (plan.overview_from_tiles) AddToOverview(tile, w, plan.factor, overview);
  std::vector<CraterDetection> found;
  {
    const internal::UseEdgeScratch use(scratch.get());
    // Only craters centred in the core come back: the tile skips fitting the others.
    const cv::Rect2d core(w.core_c0 - w.c0, w.core_r0 - w.r0, w.core_c1 - w.core_c0,
                          w.core_r1 - w.core_r0);
    found = internal::DetectCratersInCore(tile, source, plan.tile_options, core);
  }
  scratch_pool->Release(std::move(scratch));
  for (CraterDetection& d : found) d = internal::ShiftedDetection(d, w.c0, w.r0, 1.0);
  return found;
}

// The craters of all tiles, joined in tile order; fills `overview` when the plan says so.
std::vector<CraterDetection> DetectInTiles(const internal::RasterLevels& levels, RimSource source,
                                           const TilePlan& plan, const CraterDetectorOptions& o,
                                           const ProgressCallback& progress, cv::Mat* overview) {
  // Each tile's craters in its own slot, joined in tile order below: the result does not depend
  // on the order in which the tiles finish (SuppressDuplicateCraters keeps the first of equally
  // confident duplicates).
  std::vector<std::vector<CraterDetection>> per_tile(static_cast<size_t>(plan.tile_count));
  std::mutex progress_mutex;  // the callback is called by one task at a time
  std::atomic<int> done{0};
  std::atomic<bool> cancelled{false};
  const double overview_share = plan.need_overview ? 0.2 : 0.0;
  if (plan.run_tiles) {
    // Edge detection temporaries, reused by consecutive tiles (edge_scratch.h), sized once for
    // the largest level of a padded tile (+ the edge map's 1 px border).
    const size_t level_side =
        static_cast<size_t>(plan.padded) * (plan.tile_options.SearchesUpsampledLevel() ? 2 : 1) + 2;
    internal::EdgeScratchPool scratch_pool(level_side * level_side);
    // Each thread reads through its own GDAL handle (raster_levels.h), so that decoding (a fifth
    // of the CPU time on compressed tiles) runs in parallel instead of one thread waiting for the
    // other's read. TBB hands each thread a contiguous run of tiles, so most blocks shared by
    // neighbouring tiles' overlaps are still decoded once, in that handle's cache.
    tbb::parallel_for(0, plan.tile_count, [&](int t) {
      if (cancelled) return;
      per_tile[static_cast<size_t>(t)] =
          DetectInTile(plan, t, source, o, levels, &scratch_pool, overview);
      std::lock_guard<std::mutex> lock(progress_mutex);
      const double fraction =
          (1.0 - overview_share) * (++done) / static_cast<double>(plan.tile_count);
      if (progress && !progress(fraction, "craters: tiles")) cancelled = true;
    });
    if (cancelled) throw Error("crater detection cancelled");
  }
  std::vector<CraterDetection> all;
  for (std::vector<CraterDetection>& found : per_tile) {
    all.insert(all.end(), std::make_move_iterator(found.begin()),
               std::make_move_iterator(found.end()));
  }
  return all;
}

// An overview crater (raster pixels) re-fitted on a window around its rim at the finest
// resolution that fits a padded tile; unchanged where that is the overview's or the fit fails.
CraterDetection RefinedOverviewCrater(const RasterDataset& dataset, RimSource source,
                                      const TilePlan& plan, const CraterDetectorOptions& o,
                                      const CraterDetection& coarse) {
  CraterDetection d = internal::ShiftedDetection(coarse, 0.0, 0.0, plan.factor);
  const double reach = 1.2 * d.ellipse.semi_major + 8.0;
  const int c0 = std::max(0, static_cast<int>(d.ellipse.center.x() - reach));
  const int r0 = std::max(0, static_cast<int>(d.ellipse.center.y() - reach));
  const int c1 = std::min(plan.width, static_cast<int>(d.ellipse.center.x() + reach) + 1);
  const int r1 = std::min(plan.height, static_cast<int>(d.ellipse.center.y() + reach) + 1);
  int fine = 1;
  while (std::max(c1 - c0, r1 - r0) / fine > plan.padded) fine *= 2;
  if (fine >= plan.factor) return d;
  const cv::Mat window = ReadDecimated(dataset, {c0, r0, c1 - c0, r1 - r0}, fine);
  Ellipse local = d.ellipse;
  local.center = (local.center - Eigen::Vector2d(c0, r0)) / fine;
  local.semi_major /= fine;
  local.semi_minor /= fine;
  CraterDetectorOptions window_options = o;
  window_options.dtm_posting = o.dtm_posting * fine;  // ground size of a window pixel
  if (auto refined = RefineCrater(window, source, local, window_options)) {
    const double confidence = d.confidence;
    d = internal::ShiftedDetection(*refined, c0, r0, fine);
    d.confidence = std::max(confidence, d.confidence);
    d.pyramid_level = coarse.pyramid_level + static_cast<int>(std::log2(plan.factor));
  }
  return d;
}

// The craters larger than the tiles', found on the decimated overview (read now unless the
// tiles filled it) and re-fitted at a finer resolution.
std::vector<CraterDetection> DetectInOverview(const RasterDataset& dataset, RimSource source,
                                              const TilePlan& plan, const CraterDetectorOptions& o,
                                              cv::Mat overview) {
  if (!plan.overview_from_tiles) {
    overview = ReadDecimated(dataset, dataset.FullWindow(), plan.factor);
  }
  CraterDetectorOptions overview_options = o;
  overview_options.min_diameter_px = std::max(4.0, 0.9 * plan.tile_max_diameter / plan.factor);
  overview_options.max_diameter_px =
      o.max_diameter_px == 0.0 ? 0.0 : o.max_diameter_px / plan.factor;
  if (overview_options.max_diameter_px != 0.0 &&
      overview_options.max_diameter_px < overview_options.min_diameter_px) {
    overview_options.max_diameter_px = overview_options.min_diameter_px;
  }
  // Each overview crater is re-fitted below at the finest resolution that fits a tile.
  overview_options.refine_to_full_resolution = false;
  std::vector<CraterDetection> found;
  for (const CraterDetection& coarse : DetectCraters(overview, source, overview_options)) {
    found.push_back(RefinedOverviewCrater(dataset, source, plan, o, coarse));
  }
  return found;
}

// The edge detector on a raster: whole when it fits one padded tile, else tiles for craters up to
// the overlap and the overview for larger ones.
std::vector<CraterDetection> DetectEdgesInRaster(const internal::RasterLevels& levels,
                                                 RimSource source, const CraterDetectorOptions& o,
                                                 const ProgressCallback& progress) {
  const RasterDataset& dataset = levels.dataset();
  const int width = levels.width(), height = levels.height();
  const int padded = o.tile_size + 2 * o.tile_overlap;
  if (width <= padded && height <= padded) {
    return DetectCraters(levels.Read(0, cv::Rect(0, 0, width, height)), source, o, progress);
  }
  const TilePlan plan = PlanTiles(width, height, o);
  cv::Mat overview;
  if (plan.overview_from_tiles)
    overview = cv::Mat(height / plan.factor, width / plan.factor, CV_32F);
  std::vector<CraterDetection> all = DetectInTiles(levels, source, plan, o, progress, &overview);
  if (plan.need_overview) {
    for (CraterDetection& d : DetectInOverview(dataset, source, plan, o, overview)) {
      all.push_back(std::move(d));
    }
  }
  ReportProgress(progress, 1.0, "craters: done");
  return KeepWithinDiameterLimits(SuppressDuplicateCraters(std::move(all)), o);
}

}  // namespace

std::vector<CraterDetection> DetectCratersInImage(const cv::Mat& image, RimSource source,
                                                  const CraterDetectorOptions& o,
                                                  const ProgressCallback& progress) {
  o.Check();
  if (source == RimSource::kDtm || o.method == CraterMethod::kEdges) {
    return DetectCraters(image, source, o, progress);
  }
  if (o.method == CraterMethod::kLearned)
    return DetectCratersLearned(image, o, o.learned, progress);
  std::vector<CraterDetection> rims =
      DetectCraters(image, source, EdgeDetectorHalf(o), SubProgress(progress, 0.0, 0.3));
  internal::LearnedFinds found = internal::DetectCratersLearnedInImage(
      image, NetworkHalf(o), o.learned, /*with_support=*/true, SubProgress(progress, 0.3, 1.0));
  return MergeEdgeAndLearnedCraters(std::move(rims), found.craters, found.support);
}

std::vector<CraterDetection> DetectCratersInRaster(const RasterDataset& dataset, RimSource source,
                                                   const CraterDetectorOptions& o,
                                                   const ProgressCallback& progress) {
  o.Check();
  if (source == RimSource::kImage && o.method == CraterMethod::kLearned) {
    return DetectCratersLearned(dataset, o, o.learned, progress);
  }
  if (source == RimSource::kImage && o.method == CraterMethod::kCombined) {
    // Both halves read one decoding of a large raster (raster_levels.h).
    const internal::RasterLevels levels(dataset, /*decode_once=*/true);
    std::vector<CraterDetection> rims =
        DetectEdgesInRaster(levels, source, EdgeDetectorHalf(o), SubProgress(progress, 0.0, 0.3));
    internal::LearnedFinds found = internal::DetectCratersLearnedOn(
        levels, NetworkHalf(o), o.learned, /*with_support=*/true, SubProgress(progress, 0.3, 1.0));
    return MergeEdgeAndLearnedCraters(std::move(rims), found.craters, found.support);
  }
  // The edge detector reads each tile once: no level files.
  return DetectEdgesInRaster(internal::RasterLevels(dataset, /*decode_once=*/false), source, o,
                             progress);
}

}  // namespace areomap
