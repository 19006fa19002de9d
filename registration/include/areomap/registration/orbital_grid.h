// Pixel grids on Mars: going between pixel coordinates of a georeferenced raster and
// planetocentric latitude / east longitude, and from one raster's pixels to another's (a rover
// orthophoto on its local projection to an orbital image on its own).
//
// Pixel coordinates follow GDAL (pixel centre at +0.5). Geographic coordinates are
// planetocentric latitude and east longitude [rad] of the point on the CRS's ellipsoid (or
// sphere) surface, h = 0; latitude and longitude are what two Mars CRSs agree on, whatever
// their radii. Per-point failures (outside a projection's domain) give NaN, never an exception.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include <Eigen/Core>

#include "areomap/map/body.h"
#include "areomap/map/crs.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/raster.h"

namespace areomap {

class PixelGrid {
 public:
  // Throws areomap::Error naming `name` if the CRS cannot be parsed or is not on Mars.
  PixelGrid(const GeoTransform& geotransform, const std::string& crs_wkt, const std::string& name);

  // Pixel (col, row) -> planetocentric lat, east lon [rad]; std::nullopt where undefined.
  std::optional<Geographic> PixelToGeographic(const Eigen::Vector2d& pixel) const;
  // Planetocentric lat, east lon [rad] -> pixel (col, row); NaN where undefined.
  Eigen::Vector2d GeographicToPixel(const Geographic& g) const;
  // The pixel (col, row) where the CRS maps a point given in MBF [m]; NaN where undefined. Off
  // the ellipsoid this is not GeographicToPixel of the point's latitude: the points of a map
  // pixel lie on one line (a sphere-based CRS's: the radial line, as map-projected images,
  // geodesy.h MbfOnRadialLine), and a point h below the ellipsoid lies h (lat_g - lat_c) away
  // from its foot point's radial line (5.5 m at 14.6 deg latitude for h = -1900 m).
  Eigen::Vector2d PointToPixel(const Eigen::Vector3d& p_in_mbf) const;
  // The point [MBF, m] of `pixel`'s line at height `h` above `body`'s ellipsoid [m]
  // (CrsTransform::ToMbfAtHeight); std::nullopt where undefined.
  std::optional<Eigen::Vector3d> PixelToPoint(const Eigen::Vector2d& pixel, const Body& body,
                                              double h) const;
  // Local east and north [m] at `pixel` of a step of one pixel along the columns (first
  // column of the result) and along the rows (second column), from finite differences.
  Eigen::Matrix2d EastNorthPerPixel(const Eigen::Vector2d& pixel) const;

  const GeoTransform& geotransform() const { return geotransform_; }
  const std::string& crs_wkt() const { return crs_wkt_; }
  const CrsDescription& description() const { return transform_->description(); }
  const Body& body() const { return transform_->description().body; }
  const std::string& name() const { return name_; }

 private:
  GeoTransform geotransform_;
  std::string crs_wkt_;
  std::string name_;
  std::shared_ptr<CrsTransform> transform_;
};

// Pixel coordinates of one grid -> pixel coordinates of another, through planetocentric
// coordinates; a pure affine map when both grids share the same CRS.
class GridMapping {
 public:
  GridMapping(const PixelGrid& from, const PixelGrid& to);
  // NaN where either CRS cannot map the point.
  Eigen::Vector2d Apply(const Eigen::Vector2d& from_pixel) const;

 private:
  PixelGrid from_;  // Copies share the CRS transforms.
  PixelGrid to_;
  bool same_crs_ = false;
};

}  // namespace areomap
