// The part of a raster that holds data: found by reading one band in strips, so that a caller can
// read just that window of a large, mostly empty raster (or refuse one with no data) with memory
// by a strip rather than by the raster.
#pragma once

#include <optional>

#include "areomap/map/raster.h"

namespace areomap {

// Which cells of a band ValidPixelWindow counts, the band read as ReadWindowFloat reads it
// (nodata and non-finite values are NaN): finite values, or values greater than 0 (a validity
// band, where 0 and NaN mean invalid).
enum class ValidCells { kFinite, kPositive };

// The smallest window of `dataset` that holds every valid cell of band `band` (1-based) by
// `rule`, the band read in strips of 256 rows (memory by a strip); std::nullopt when no cell is
// valid. Throws areomap::Error as ReadWindowFloat (a bad band, an unreadable file).
std::optional<PixelWindow> ValidPixelWindow(const RasterDataset& dataset, int band,
                                            ValidCells rule);

// The geotransform of a window's pixels: pixel (0, 0) of the result is pixel
// (window.col0, window.row0) of `transform` (any affine transform, rotated ones included).
GeoTransform WindowTransform(const GeoTransform& transform, const PixelWindow& window);

}  // namespace areomap
