// Coordinate reference systems through GDAL/OGR and PROJ: building Mars CRSs, describing any
// CRS in Mars terms, and moving coordinates between a CRS and Mars body-fixed XYZ (MBF).
//
// Axis order is "traditional GIS" everywhere: x/easting/longitude first, latitude second.
// Geographic CRS coordinates are in degrees at this interface (it is an I/O boundary).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "areomap/map/body.h"
#include "areomap/map/geodesy.h"

namespace areomap {

// WKT2 of the geographic CRS of a body: IAU_2015:49900 for the IAU sphere, IAU_2015:49902
// (planetocentric, east) for the IAU 2000 ellipsoid, a custom one otherwise.
std::string GeographicCrsWkt(const Body& body);

// WKT2 of a projected CRS on `body` (used by MapProjection::Wkt). `method` is
// "Equirectangular", "Sinusoidal" or "PolarStereographic"; parameters in radians under the
// keys "center_lat", "center_lon". Throws areomap::Error for an unknown method.
std::string ProjectedCrsWkt(const Body& body, std::string_view method,
                            const std::map<std::string, double>& parameters);

// A CRS described in Mars terms.
struct CrsDescription {
  std::string name;       // The CRS's own name.
  std::string authority;  // e.g. "IAU_2015:49910", empty if none.
  std::string ellipsoid_name;
  Body body;             // Radii of the CRS's ellipsoid or sphere.
  bool is_mars = false;  // Radii within Mars's range (local radii included).
  bool is_projected = false;
  bool is_geocentric = false;  // Cartesian body-fixed CRS.
  bool IsGeographic() const { return !is_projected && !is_geocentric; }
  LatitudeType latitude_type = LatitudeType::kPlanetographic;
  LongitudeDirection longitude_direction = LongitudeDirection::kEast;
  std::string projection_method;                        // Empty for a geographic CRS.
  std::map<std::string, double> projection_parameters;  // Name -> value as WKT gives it.
};

class Crs {
 public:
  // Accepts anything GDAL's SetFromUserInput takes: "IAU_2015:49910", WKT, a PROJ string.
  // Throws areomap::Error("unknown CRS '<text>': ...") otherwise.
  static Crs FromUserInput(std::string_view text);
  // `source` names where the WKT came from, for error messages (e.g. a file name).
  static Crs FromWkt(std::string_view wkt, std::string_view source);

  std::string Wkt() const;  // WKT2_2019.
  const std::string& source() const { return source_; }
  CrsDescription Describe() const;
  // Throws areomap::Error naming `source()` if the CRS is not on Mars.
  void RequireMars() const;

 private:
  struct Impl;
  Crs(std::shared_ptr<const Impl> impl, std::string source)
      : impl_(std::move(impl)), source_(std::move(source)) {}
  std::shared_ptr<const Impl> impl_;
  std::string source_;
  friend class CrsTransform;
};

// Converts coordinates between a CRS and MBF. Per-point failures (outside the projection's
// domain, NaN) give std::nullopt; construction throws areomap::Error if PROJ finds no
// transformation between the CRS and its own geographic CRS.
class CrsTransform {
 public:
  explicit CrsTransform(const Crs& crs);
  ~CrsTransform();
  CrsTransform(CrsTransform&&) noexcept;
  CrsTransform& operator=(CrsTransform&&) noexcept;

  // (x, y, z) in the CRS (z: height above its ellipsoid [m]) -> MBF [m].
  std::optional<Eigen::Vector3d> ToMbf(const Eigen::Vector3d& xyz_in_crs) const;
  // The point [MBF, m] of the CRS's line of constant map (x, y) whose height above `body`'s
  // ellipsoid is `h` [m]; the CRS's own heights along that line differ from `body`'s by the
  // separation of the two surfaces, which changes over the map. std::nullopt where undefined.
  std::optional<Eigen::Vector3d> ToMbfAtHeight(const Eigen::Vector2d& xy, const Body& body,
                                               double h) const;
  // MBF [m] -> (x, y, z) in the CRS.
  std::optional<Eigen::Vector3d> FromMbf(const Eigen::Vector3d& p_in_mbf) const;
  // Map (x, y) -> planetocentric latitude, east longitude [rad] on the CRS's ellipsoid.
  std::optional<Geographic> ToPlanetocentric(const Eigen::Vector2d& xy) const;
  // Map (x, y) -> latitude, longitude [deg] in the CRS's own geographic CRS (what gdalinfo
  // prints as corner coordinates): (lon, lat) in its latitude type and longitude direction.
  std::optional<Eigen::Vector2d> ToOwnGeographic(const Eigen::Vector2d& xy) const;

  const CrsDescription& description() const { return description_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  CrsDescription description_;
};

}  // namespace areomap
