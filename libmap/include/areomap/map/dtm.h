// Rover DTMs: stereo point clouds of one or more sites gridded on a map (dtm_gridding.h) and
// written as a GeoTIFF with a Mars CRS.
//
// Frames: each cloud is in its site frame (point_cloud.h), placed on Mars by a SiteGeoreference
// (site_georeference.h: a site pose in the mission, bundle-adjusted or from telemetry), and
// carried into a MapFrame: (x, y) [m] in the map's projected CRS, elevation = height above the
// body's ellipsoid [m], covariances rotated with the map axes.
//
// Multi-site: every site is gridded on its own window of one common grid, then the sites are
// merged cell by cell with inverse-variance weights from their sigma layers (a far, noisy part
// of one site yields to a near part of another); count sums; stddev is that of the site that
// weighs most in the cell.
//
// Failure: an empty cloud, a non-finite point or invalid options throw areomap::Error naming the
// cloud (its `frame`) or the field.
#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include "areomap/map/dtm_gridding.h"
#include "areomap/map/point_cloud.h"
#include "areomap/map/progress.h"
#include "areomap/map/raster.h"
#include "areomap/map/site_georeference.h"

namespace areomap {

// One site's cloud and where the site is.
struct SiteCloud {
  const PointCloud* cloud = nullptr;
  SiteGeoreference georef;
};

struct DtmOptions {
  double posting_m = 0.1;        // Cell size [m] (a multiple of it becomes the grid origin).
  std::optional<GridSpec> grid;  // Use this grid instead of one covering the points.
  // Method, TIN edge limit, IDW parameters; MakeDtm sets `viewpoint` to each site's camera.
  GriddingOptions gridding{.max_edge_per_range = 0.1};
  void Check() const;  // Throws areomap::Error naming the field.
};

struct Dtm {
  GriddedLayers layers;
  std::string crs_wkt;  // The map frame's projected CRS.

  // Bands "elevation", "count", "stddev", "sigma" as Float32, nodata NaN (count is 0 there).
  GeoRaster ToGeoRaster() const;
};

// The cloud's points on the map. Throws areomap::Error (see above).
std::vector<GridPoint> PointsOnMap(const PointCloud& cloud, const SiteGeoreference& site,
                                   const MapFrame& map);

// Grids and merges the sites. `progress` may cancel (throws areomap::Error).
Dtm MakeDtm(const std::vector<SiteCloud>& sites, const MapFrame& map, const DtmOptions& options,
            const ProgressCallback& progress = nullptr);

// Merges per-site layers (each on a window of `grid`, aligned with it) into one DTM on `grid`.
GriddedLayers MergeGriddedLayers(const std::vector<GriddedLayers>& sites, const GridSpec& grid);

// Writes the DTM as a tiled, compressed GeoTIFF, atomically.
void WriteDtm(const std::filesystem::path& path, const Dtm& dtm);

// Reads a DTM GeoTIFF: band 1 is the elevation; the count, stddev and sigma bands of WriteDtm's
// layout are read when present (else 0 / NaN). Throws areomap::Error naming the file when it is
// not a north-up raster with square cells and a CRS.
Dtm ReadDtm(const std::filesystem::path& path);
// The same, only the cells of `window` (a window of the file's grid, GridSpec::Window): memory
// by the window, not the raster. Throws areomap::Error naming the file when `window` is not one.
Dtm ReadDtm(const std::filesystem::path& path, const GridSpec& window);

// The grid of a north-up raster with square cells; throws areomap::Error naming `source`.
GridSpec GridOfRaster(const RasterInfo& info, const std::string& source);

}  // namespace areomap
