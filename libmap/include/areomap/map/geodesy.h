// Coordinates on Mars: latitude types, longitude conventions, body-fixed Cartesian (MBF),
// local east-north-up (ENU) and the MER site frame (X north, Y east, Z down).
//
// Units: radians and metres throughout; degrees only at I/O (see DegFromRad/RadFromDeg).
// Conventions (DESIGN.md): planetocentric latitude and east longitude by default;
// planetographic latitude and west longitude are supported (ISIS and MOC conventions).
//
// Heights: `h` is the height above the body's ellipsoid along the ellipsoid normal, and the
// planetocentric latitude of a point with h != 0 is that of its foot point on the ellipsoid.
// This is PROJ's convention for the IAU_2015 "Ocentric" CRSs, so results compare directly with
// cs2cs. The planetocentric latitude of the point itself and its distance from the centre are
// given by SphericalFromMbf().
//
// The geodetic math is GeographicLib's (Geocentric, LocalCartesian); nothing is re-derived.
#pragma once

#include <numbers>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "areomap/map/body.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

constexpr double RadFromDeg(double deg) { return deg * (std::numbers::pi / 180.0); }
constexpr double DegFromRad(double rad) { return rad * (180.0 / std::numbers::pi); }

enum class LatitudeType { kPlanetocentric, kPlanetographic };
enum class LongitudeDirection { kEast, kWest };
enum class LongitudeDomain { kPlusMinus180, kZeroTo360 };

std::string ToString(LatitudeType type);
std::string ToString(LongitudeDirection direction);
std::string ToString(LongitudeDomain domain);
LatitudeType LatitudeTypeFromString(std::string_view text);  // Throws areomap::Error.
LongitudeDirection LongitudeDirectionFromString(std::string_view text);
LongitudeDomain LongitudeDomainFromString(std::string_view text);  // "180" or "360".

// How a (lat, lon) pair is to be read or written.
struct GeographicConvention {
  LatitudeType latitude = LatitudeType::kPlanetocentric;
  LongitudeDirection longitude = LongitudeDirection::kEast;
  LongitudeDomain domain = LongitudeDomain::kPlusMinus180;
};

// A point given by latitude, longitude [rad] and height above the ellipsoid [m], in the
// convention that accompanies it.
struct Geographic {
  double lat = 0.0;
  double lon = 0.0;
  double h = 0.0;
};

// Latitude conversions at the ellipsoid surface: tan(lat_g) = (a/b)^2 tan(lat_c).
// Valid for |lat| <= pi/2; exact at the poles; identity on a sphere.
double PlanetographicFromPlanetocentric(const Body& body, double lat_c);
double PlanetocentricFromPlanetographic(const Body& body, double lat_g);

// Wraps a longitude [rad] into [-pi, pi) or [0, 2 pi).
double WrapLongitude(double lon, LongitudeDomain domain);

// Returns true if |lat| <= pi/2 and all members are finite.
bool IsValid(const Geographic& g);

// Converts between conventions on the same body. Throws nothing; returns NaNs for NaN input.
Geographic ConvertGeographic(const Body& body, const Geographic& g,
                             const GeographicConvention& from, const GeographicConvention& to);

// (lat, lon, h) in `convention` <-> MBF XYZ [m]. Wraps GeographicLib::Geocentric.
Eigen::Vector3d MbfFromGeographic(const Body& body, const Geographic& g,
                                  const GeographicConvention& convention = {});
Geographic GeographicFromMbf(const Body& body, const Eigen::Vector3d& p_in_mbf,
                             const GeographicConvention& convention = {});

// True planetocentric spherical coordinates of a point: latitude and east longitude of the
// point itself [rad] and its distance from the body centre [m] (MOLA/ISIS "radius").
struct Spherical {
  double lat = 0.0;
  double lon = 0.0;
  double radius = 0.0;
};
Spherical SphericalFromMbf(const Eigen::Vector3d& p_in_mbf);
Eigen::Vector3d MbfFromSpherical(const Spherical& s);

// The point whose own planetocentric latitude and east longitude [rad] are (lat, lon) (it lies
// on that radial line, as map-projected ISIS/HiRISE pixels do) and whose height above the
// body's ellipsoid is h [m]. This differs from MbfFromGeographic's foot-point convention by
// h (lat_g - lat_c) horizontally: 5.5 m at 14.6 deg latitude for h = -1900 m.
Eigen::Vector3d MbfOnRadialLine(const Body& body, double lat, double lon, double h);

// Local level frames at an origin given in the default convention (planetocentric, east).
// ENU: x east, y north, z up along the ellipsoid normal (GeographicLib::LocalCartesian axes).
Rigid3d EnuFromMbf(const Body& body, const Geographic& origin);
// MER site frame: x north, y east, z down (the ellipsoid normal, pointing into the ground).
Rigid3d SiteFromEnu();
Rigid3d SiteFromMbf(const Body& body, const Geographic& origin);

}  // namespace areomap
