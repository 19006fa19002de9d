// Orthomosaics: per-site orthophotos (orthophoto.h) blended on one grid with feathered seams,
// keeping a validity mask, a resolution map and the source-image id. This is the rover product
// matched to HiRISE, so it is written with its Mars CRS, nodata and the mask.
//
// Blending: each orthophoto's weight at a cell is f(d) / resolution^2, where d is the distance
// [m] from the cell to the nearest cell another orthophoto covers and this one does not (a seam;
// the mosaic's outer edge is none) and f(d) = min(1, d / feather_m): seams fade over
// `feather_m`, and where sites overlap the finer ground sample dominates. The image is the weighted
// mean; resolution and source id are those of the orthophoto that weighs most.
//
// Frames: all orthophotos are windows of `grid` (same posting and alignment, e.g. made from one
// merged DTM); map units [m].
// Failure: an orthophoto that is not a window of `grid`, or invalid options, throw areomap::Error.
#pragma once

#include <string>
#include <vector>

#include "areomap/map/dtm_gridding.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/progress.h"

namespace areomap {

struct MosaicOptions {
  double feather_m = 1.0;  // Width of the blend at an orthophoto's edge [m].
  void Check() const;      // Throws areomap::Error naming the field.
};

// The mosaic on `grid`, in the CRS `crs_wkt`.
Orthophoto MakeOrthomosaic(const std::vector<Orthophoto>& orthophotos, const GridSpec& grid,
                           const std::string& crs_wkt, const MosaicOptions& options,
                           const ProgressCallback& progress = nullptr);

// The grid covering every orthophoto (all must share posting and alignment).
GridSpec CommonGrid(const std::vector<Orthophoto>& orthophotos);

}  // namespace areomap
