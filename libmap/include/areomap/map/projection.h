// Map projections used for Mars products, forward and inverse, with the matching CRS.
//
// Geographic input/output is planetocentric latitude and east longitude [rad] (the default
// GeographicConvention); map coordinates are metres. Ellipsoidal projections convert to
// planetographic latitude internally, which is how PROJ treats the IAU_2015 "Ocentric" CRSs,
// so Wkt() describes exactly the mapping Forward() computes.
//
// - Equirectangular: on a sphere (ISIS and HiRISE RDR): x = R (lon - lon0) cos(lat_ts),
//   y = R lat. R is the body's equatorial radius or, as HiRISE RDR labels do, the local radius
//   of the ellipsoid at the centre latitude.
// - Sinusoidal: ellipsoidal when the body is (PROJ `sinu`), via GeographicLib::Ellipsoid.
// - Polar stereographic (north or south), scale 1 at a latitude of true scale (variant B),
//   via GeographicLib::PolarStereographic.
//
// Forward() returns NaNs for points the projection cannot map (the opposite pole of a polar
// stereographic projection, non-finite input); it never throws.
#pragma once

#include <string>

#include <Eigen/Core>

#include "areomap/map/body.h"
#include "areomap/map/geodesy.h"

namespace areomap {

enum class ProjectionType { kEquirectangular, kSinusoidal, kPolarStereographic };
enum class Pole { kNorth, kSouth };
enum class EquirectangularRadius {
  kEquatorial,             // R = body.a
  kLocalAtCenterLatitude,  // R = ellipsoid radius at the centre latitude (HiRISE RDR)
};

std::string ToString(ProjectionType type);

class MapProjection {
 public:
  // center_lat: latitude of true scale [rad]; center_lon: central meridian [rad, east].
  static MapProjection Equirectangular(
      const Body& body, double center_lat, double center_lon,
      EquirectangularRadius radius = EquirectangularRadius::kEquatorial);
  static MapProjection Sinusoidal(const Body& body, double center_lon);
  // latitude_of_true_scale [rad] must lie in the pole's hemisphere (e.g. +-pi/2 for k0 = 1).
  static MapProjection PolarStereographic(const Body& body, Pole pole, double center_lon,
                                          double latitude_of_true_scale);

  // Planetocentric lat, east lon [rad] -> (x, y) [m]. Heights are ignored.
  Eigen::Vector2d Forward(const Geographic& g) const;
  // (x, y) [m] -> planetocentric lat, east lon in (-pi, pi] [rad], h = 0.
  Geographic Inverse(const Eigen::Vector2d& xy) const;

  // WKT2 (2019) of the projected CRS. The base geographic CRS is an IAU_2015 one where the
  // body matches (49900 for the IAU sphere, 49902 for the IAU 2000 ellipsoid).
  std::string Wkt() const;

  ProjectionType type() const { return type_; }
  // The surface the projection is computed on (a sphere for equirectangular).
  const Body& surface() const { return surface_; }
  double center_lat() const { return center_lat_; }
  double center_lon() const { return center_lon_; }

 private:
  MapProjection(ProjectionType type, const Body& body, const Body& surface, double center_lat,
                double center_lon)
      : type_(type),
        body_(body),
        surface_(surface),
        center_lat_(center_lat),
        center_lon_(center_lon) {}

  ProjectionType type_;
  Body body_;     // The body whose planetocentric coordinates come in.
  Body surface_;  // The body the projection formulas use.
  double center_lat_;
  double center_lon_;
};

}  // namespace areomap
