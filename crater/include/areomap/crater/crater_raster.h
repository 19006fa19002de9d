// Crater detection on rasters of any size, read by windows: tiles with overlap at full
// resolution for craters up to the overlap in diameter, plus one decimated overview (no larger
// than a padded tile; averaged from the tiles as they are read, or read in strips when no tile
// runs, ReadDecimated in raster.h) for larger ones, which are then re-fitted on a window read at
// the finest resolution that fits a tile. Memory is bounded by a few tiles, not by the raster.
//
// Frame: full-resolution pixel coordinates of the raster (GDAL convention), as DetectCraters.
// Failure: unreadable rasters throw areomap::Error (from RasterDataset); content never does.
#pragma once

#include <vector>

#include "areomap/crater/crater_detector.h"
#include "areomap/map/raster.h"

namespace areomap {

// Band 1 of `dataset`, scale/offset applied, nodata as NaN. An image with options.method
// kLearned goes to DetectCratersLearned (learned_detector.h); otherwise the edge pipeline: tiles of
// options.tile_size (core) plus options.tile_overlap on each side run in parallel (TBB); a raster
// no bigger than one padded tile is processed whole. Progress per tile.
std::vector<CraterDetection> DetectCratersInRaster(const RasterDataset& dataset, RimSource source,
                                                   const CraterDetectorOptions& options = {},
                                                   const ProgressCallback& progress = nullptr);

// The same choice of detector (options.method) on an image already in memory (single band,
// CV_32F or any depth DetectCraters takes, NaN = nodata): DetectCraters for a DTM or kEdges,
// DetectCratersLearned for kLearned, both merged for kCombined. Gives the craters
// DetectCratersInRaster finds on the same pixels.
std::vector<CraterDetection> DetectCratersInImage(const cv::Mat& image, RimSource source,
                                                  const CraterDetectorOptions& options = {},
                                                  const ProgressCallback& progress = nullptr);

}  // namespace areomap
