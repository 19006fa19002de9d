// What `areomap info` reports about a raster: size, type, CRS in Mars terms, corner
// coordinates and, for labelled planetary products, the camera model and frames.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "areomap/map/crs.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/pds_label.h"
#include "areomap/map/raster.h"

namespace areomap {

struct CornerCoordinate {
  std::string name;       // "upper_left", "lower_left", "upper_right", "lower_right", "center".
  Eigen::Vector2d pixel;  // GDAL pixel coordinates (corner of the raster = integer).
  Eigen::Vector2d map;    // Map coordinates in the raster's CRS.
  // (lon, lat) [deg] in the CRS's own geographic CRS, as gdalinfo prints them.
  std::optional<Eigen::Vector2d> own_lon_lat_deg;
  // Planetocentric latitude, east longitude [rad] on the CRS's ellipsoid.
  std::optional<Geographic> planetocentric;
};

struct RasterDescription {
  RasterInfo info;
  std::optional<CrsDescription> crs;       // None when the raster has no CRS.
  std::vector<CornerCoordinate> corners;   // gdalinfo's order; empty without georeference.
  std::optional<ProductGeometry> product;  // From a PDS3/VICAR label, if any.
};

// Opens `path` and describes it. Throws areomap::Error for unreadable files and malformed
// labels; a raster without CRS or label is described without those parts.
RasterDescription DescribeRaster(const std::filesystem::path& path);

}  // namespace areomap
