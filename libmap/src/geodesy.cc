#include "areomap/map/geodesy.h"

#include <cmath>
#include <vector>

#include <GeographicLib/Geocentric.hpp>

#include "areomap/map/error.h"

namespace areomap {
namespace {

GeographicLib::Geocentric MakeGeocentric(const Body& body) {
  return GeographicLib::Geocentric(body.a, body.Flattening());
}

// Converts `g` to planetographic latitude, east longitude (what GeographicLib works in).
Geographic ToGeodeticEast(const Body& body, const Geographic& g,
                          const GeographicConvention& convention) {
  Geographic out = g;
  if (convention.latitude == LatitudeType::kPlanetocentric) {
    out.lat = PlanetographicFromPlanetocentric(body, g.lat);
  }
  if (convention.longitude == LongitudeDirection::kWest) out.lon = -g.lon;
  return out;
}

Geographic FromGeodeticEast(const Body& body, const Geographic& g,
                            const GeographicConvention& convention) {
  Geographic out = g;
  if (convention.latitude == LatitudeType::kPlanetocentric) {
    out.lat = PlanetocentricFromPlanetographic(body, g.lat);
  }
  if (convention.longitude == LongitudeDirection::kWest) out.lon = -g.lon;
  out.lon = WrapLongitude(out.lon, convention.domain);
  return out;
}

}  // namespace

std::string ToString(LatitudeType type) {
  return type == LatitudeType::kPlanetocentric ? "planetocentric" : "planetographic";
}
std::string ToString(LongitudeDirection direction) {
  return direction == LongitudeDirection::kEast ? "east" : "west";
}
std::string ToString(LongitudeDomain domain) {
  return domain == LongitudeDomain::kPlusMinus180 ? "180" : "360";
}
LatitudeType LatitudeTypeFromString(std::string_view text) {
  if (text == "planetocentric" || text == "ocentric") return LatitudeType::kPlanetocentric;
  if (text == "planetographic" || text == "ographic") return LatitudeType::kPlanetographic;
  throw Error("unknown latitude type '" + std::string(text) +
              "': expected planetocentric or planetographic");
}
LongitudeDirection LongitudeDirectionFromString(std::string_view text) {
  if (text == "east") return LongitudeDirection::kEast;
  if (text == "west") return LongitudeDirection::kWest;
  throw Error("unknown longitude direction '" + std::string(text) + "': expected east or west");
}
LongitudeDomain LongitudeDomainFromString(std::string_view text) {
  if (text == "180") return LongitudeDomain::kPlusMinus180;
  if (text == "360") return LongitudeDomain::kZeroTo360;
  throw Error("unknown longitude domain '" + std::string(text) + "': expected 180 or 360");
}

double PlanetographicFromPlanetocentric(const Body& body, double lat_c) {
  // atan2 form stays exact at the poles: tan(lat_g) = (a/b)^2 tan(lat_c).
  return std::atan2(body.a * body.a * std::sin(lat_c), body.b * body.b * std::cos(lat_c));
}

double PlanetocentricFromPlanetographic(const Body& body, double lat_g) {
  return std::atan2(body.b * body.b * std::sin(lat_g), body.a * body.a * std::cos(lat_g));
}

double WrapLongitude(double lon, LongitudeDomain domain) {
  if (!std::isfinite(lon)) return lon;
  double wrapped = std::remainder(lon, 2.0 * std::numbers::pi);  // In [-pi, pi].
  if (domain == LongitudeDomain::kPlusMinus180) {
    if (wrapped >= std::numbers::pi) wrapped -= 2.0 * std::numbers::pi;
  } else if (wrapped < 0.0) {
    wrapped += 2.0 * std::numbers::pi;
    if (wrapped >= 2.0 * std::numbers::pi) wrapped = 0.0;  // -0 rounding guard.
  }
  return wrapped;
}

bool IsValid(const Geographic& g) {
  return std::isfinite(g.lat) && std::isfinite(g.lon) && std::isfinite(g.h) &&
         std::abs(g.lat) <= std::numbers::pi / 2.0;
}

Geographic ConvertGeographic(const Body& body, const Geographic& g,
                             const GeographicConvention& from, const GeographicConvention& to) {
  return FromGeodeticEast(body, ToGeodeticEast(body, g, from), to);
}

Eigen::Vector3d MbfFromGeographic(const Body& body, const Geographic& g,
                                  const GeographicConvention& convention) {
  const Geographic geodetic = ToGeodeticEast(body, g, convention);
  Eigen::Vector3d xyz;
  MakeGeocentric(body).Forward(DegFromRad(geodetic.lat), DegFromRad(geodetic.lon), geodetic.h,
                               xyz.x(), xyz.y(), xyz.z());
  return xyz;
}

Geographic GeographicFromMbf(const Body& body, const Eigen::Vector3d& p_in_mbf,
                             const GeographicConvention& convention) {
  double lat_deg = 0.0, lon_deg = 0.0, h = 0.0;
  MakeGeocentric(body).Reverse(p_in_mbf.x(), p_in_mbf.y(), p_in_mbf.z(), lat_deg, lon_deg, h);
  return FromGeodeticEast(body, Geographic{RadFromDeg(lat_deg), RadFromDeg(lon_deg), h},
                          convention);
}

Spherical SphericalFromMbf(const Eigen::Vector3d& p) {
  const double horizontal = std::hypot(p.x(), p.y());
  return Spherical{std::atan2(p.z(), horizontal), std::atan2(p.y(), p.x()), p.norm()};
}

Eigen::Vector3d MbfFromSpherical(const Spherical& s) {
  return s.radius * Eigen::Vector3d(std::cos(s.lat) * std::cos(s.lon),
                                    std::cos(s.lat) * std::sin(s.lon), std::sin(s.lat));
}

Eigen::Vector3d MbfOnRadialLine(const Body& body, double lat, double lon, double h) {
  Spherical s{lat, lon, body.RadiusAtPlanetocentricLatitude(lat) + h};
  // Newton on the radius: the height grows with the radius at a rate cos(lat_g - lat_c) ~ 1.
  for (int i = 0; i < 4; ++i) {
    const double error = GeographicFromMbf(body, MbfFromSpherical(s)).h - h;
    if (std::abs(error) < 1e-9) break;
    s.radius -= error;
  }
  return MbfFromSpherical(s);
}

Rigid3d EnuFromMbf(const Body& body, const Geographic& origin) {
  const Geographic geodetic = ToGeodeticEast(body, origin, GeographicConvention{});
  // Geocentric::Forward's M (row-major) maps a vector in ENU at the point to MBF.
  std::vector<double> m(9);
  Eigen::Vector3d origin_in_mbf;
  MakeGeocentric(body).Forward(DegFromRad(geodetic.lat), DegFromRad(geodetic.lon), geodetic.h,
                               origin_in_mbf.x(), origin_in_mbf.y(), origin_in_mbf.z(), m);
  const Eigen::Matrix3d mbf_from_enu_rotation =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(m.data());
  const Eigen::Matrix3d enu_from_mbf_rotation = mbf_from_enu_rotation.transpose();
  return Rigid3d(enu_from_mbf_rotation, -(enu_from_mbf_rotation * origin_in_mbf));
}

Rigid3d SiteFromEnu() {
  Eigen::Matrix3d site_from_enu;
  site_from_enu << 0, 1, 0,  // x_site = north
      1, 0, 0,               // y_site = east
      0, 0, -1;              // z_site = down
  return Rigid3d(site_from_enu, Eigen::Vector3d::Zero());
}

Rigid3d SiteFromMbf(const Body& body, const Geographic& origin) {
  return SiteFromEnu() * EnuFromMbf(body, origin);
}

}  // namespace areomap
