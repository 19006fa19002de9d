// Crater detection on rasters of any size, read by windows: tiles with overlap at full
// resolution for craters up to the overlap in diameter, plus one decimated overview (no larger
// than a padded tile; averaged from the tiles as they are read, or read in strips when no tile
// runs) for larger ones, which are then re-fitted on a window read at the finest resolution
// that fits a tile. Memory is bounded by a few tiles, not by the raster.
//
// Frame: full-resolution pixel coordinates of the raster (GDAL convention), as DetectCraters.
// Failure: unreadable rasters throw areomap::Error (from RasterDataset); content never does.
#pragma once

#include <cstdint>
#include <vector>

#include "areomap/crater/crater_detector.h"
#include "areomap/map/raster.h"

namespace areomap {

// Band 1 of `dataset`, scale/offset applied, nodata as NaN. Tiles of options.tile_size (core)
// plus options.tile_overlap on each side run in parallel (TBB); a raster no bigger than one
// padded tile is processed whole. Progress per tile.
std::vector<CraterDetection> DetectCratersInRaster(const RasterDataset& dataset, RimSource source,
                                                   const CraterDetectorOptions& options = {},
                                                   const ProgressCallback& progress = nullptr);

// The power of two by which a width x height raster is decimated for an overview whose longer side
// is at most `max_side` px (>= 1); never so far that the shorter side falls below 1 px.
int DecimationFactor(int width, int height, int max_side);

// `window` of band 1 averaged over factor x factor blocks (factor >= 1), read in strips so that
// memory stays at the output plus one strip. Output size: window size / factor (rounded down);
// NaN where any input pixel of a block is nodata. `valid_pixels`, when given, receives the number
// of the pixels read that are valid (finite, not nodata); pixels beyond the last whole block of
// a row or column are not read.
cv::Mat ReadDecimated(const RasterDataset& dataset, const PixelWindow& window, int factor,
                      int64_t* valid_pixels = nullptr);

}  // namespace areomap
