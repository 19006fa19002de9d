#include "areomap/map/projection.h"

#include <cmath>
#include <limits>

#include <GeographicLib/Ellipsoid.hpp>
#include <GeographicLib/PolarStereographic.hpp>

#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/numbers.h"

namespace areomap {
namespace {

constexpr double kHalfPi = std::numbers::pi / 2.0;

GeographicLib::PolarStereographic MakePolar(const Body& surface, double latitude_of_true_scale) {
  GeographicLib::PolarStereographic polar(surface.a, surface.Flattening(), 1.0);
  if (std::abs(latitude_of_true_scale) < kHalfPi) {
    // GeographicLib sets the scale for the north pole; the south is its mirror image.
    polar.SetScale(DegFromRad(std::abs(latitude_of_true_scale)), 1.0);
  }
  return polar;
}

void CheckLatitude(double lat, const char* field) {
  if (!(std::isfinite(lat) && std::abs(lat) <= kHalfPi)) {
    throw Error(std::string("projection ") + field + " " + std::to_string(DegFromRad(lat)) +
                " deg is invalid: expected a latitude in [-90, 90] deg");
  }
}

void CheckLongitude(double lon, const char* field) {
  if (!std::isfinite(lon)) {
    throw Error(std::string("projection ") + field + " is not finite: expected degrees east");
  }
}

}  // namespace

std::string ToString(ProjectionType type) {
  switch (type) {
    case ProjectionType::kEquirectangular:
      return "equirectangular";
    case ProjectionType::kSinusoidal:
      return "sinusoidal";
    case ProjectionType::kPolarStereographic:
      return "polar-stereographic";
  }
  return "unknown";
}

MapProjection MapProjection::Equirectangular(const Body& body, double center_lat, double center_lon,
                                             EquirectangularRadius radius) {
  body.Check();
  CheckLatitude(center_lat, "centre latitude");
  CheckLongitude(center_lon, "centre longitude");
  if (std::abs(center_lat) >= kHalfPi) {
    throw Error("equirectangular centre latitude must be inside (-90, 90) deg: got " +
                std::to_string(DegFromRad(center_lat)));
  }
  Body surface = body.IsSphere() ? body : Body::Sphere(body.a, body.name + " equatorial sphere");
  if (radius == EquirectangularRadius::kLocalAtCenterLatitude && !body.IsSphere()) {
    surface = Body::Sphere(body.RadiusAtPlanetocentricLatitude(center_lat),
                           body.name + " local radius sphere");
  }
  return MapProjection(ProjectionType::kEquirectangular, body, surface, center_lat, center_lon);
}

MapProjection MapProjection::Sinusoidal(const Body& body, double center_lon) {
  body.Check();
  CheckLongitude(center_lon, "centre longitude");
  return MapProjection(ProjectionType::kSinusoidal, body, body, 0.0, center_lon);
}

MapProjection MapProjection::PolarStereographic(const Body& body, Pole pole, double center_lon,
                                                double latitude_of_true_scale) {
  body.Check();
  CheckLongitude(center_lon, "centre longitude");
  CheckLatitude(latitude_of_true_scale, "latitude of true scale");
  const bool north = pole == Pole::kNorth;
  if (north ? latitude_of_true_scale <= 0.0 : latitude_of_true_scale >= 0.0) {
    throw Error("polar stereographic latitude of true scale " +
                std::to_string(DegFromRad(latitude_of_true_scale)) +
                " deg must lie in the hemisphere of the " + (north ? "north" : "south") + " pole");
  }
  return MapProjection(ProjectionType::kPolarStereographic, body, body, latitude_of_true_scale,
                       center_lon);
}

Eigen::Vector2d MapProjection::Forward(const Geographic& g) const {
  if (!IsValid(g)) return {kNaN, kNaN};
  const double dlon = WrapLongitude(g.lon - center_lon_, LongitudeDomain::kPlusMinus180);
  switch (type_) {
    case ProjectionType::kEquirectangular: {
      // Planetocentric coordinates are mapped onto the sphere unchanged (ISIS convention).
      const double r = surface_.a;
      return {r * dlon * std::cos(center_lat_), r * g.lat};
    }
    case ProjectionType::kSinusoidal: {
      const double lat_g = PlanetographicFromPlanetocentric(body_, g.lat);
      const GeographicLib::Ellipsoid ellipsoid(surface_.a, surface_.Flattening());
      const double e2 = ellipsoid.EccentricitySq();
      const double s = std::sin(lat_g);
      const double n = surface_.a / std::sqrt(1.0 - e2 * s * s);  // Prime vertical radius.
      return {n * std::cos(lat_g) * dlon, ellipsoid.MeridianDistance(DegFromRad(lat_g))};
    }
    case ProjectionType::kPolarStereographic: {
      const bool north = center_lat_ > 0.0;
      const double lat_g = PlanetographicFromPlanetocentric(body_, g.lat);
      if (north ? lat_g <= -kHalfPi : lat_g >= kHalfPi) return {kNaN, kNaN};
      double x = 0.0, y = 0.0, gamma = 0.0, k = 0.0;
      MakePolar(surface_, center_lat_)
          .Forward(north, DegFromRad(lat_g), DegFromRad(dlon), x, y, gamma, k);
      return {x, y};
    }
  }
  return {kNaN, kNaN};
}

Geographic MapProjection::Inverse(const Eigen::Vector2d& xy) const {
  if (!xy.allFinite()) return Geographic{kNaN, kNaN, 0.0};
  Geographic out;
  switch (type_) {
    case ProjectionType::kEquirectangular: {
      const double r = surface_.a;
      out.lat = xy.y() / r;
      out.lon = center_lon_ + xy.x() / (r * std::cos(center_lat_));
      if (std::abs(out.lat) > kHalfPi) return Geographic{kNaN, kNaN, 0.0};
      break;
    }
    case ProjectionType::kSinusoidal: {
      const GeographicLib::Ellipsoid ellipsoid(surface_.a, surface_.Flattening());
      const double mu = 90.0 * xy.y() / ellipsoid.QuarterMeridian();
      if (std::abs(mu) > 90.0) return Geographic{kNaN, kNaN, 0.0};
      const double lat_g = RadFromDeg(ellipsoid.InverseRectifyingLatitude(mu));
      const double e2 = ellipsoid.EccentricitySq();
      const double s = std::sin(lat_g);
      const double n = surface_.a / std::sqrt(1.0 - e2 * s * s);
      const double parallel_radius = n * std::cos(lat_g);
      const double dlon = parallel_radius > 0.0 ? xy.x() / parallel_radius : 0.0;
      if (std::abs(dlon) > std::numbers::pi) return Geographic{kNaN, kNaN, 0.0};
      out.lat = PlanetocentricFromPlanetographic(body_, lat_g);
      out.lon = center_lon_ + dlon;
      break;
    }
    case ProjectionType::kPolarStereographic: {
      double lat_deg = 0.0, lon_deg = 0.0, gamma = 0.0, k = 0.0;
      MakePolar(surface_, center_lat_)
          .Reverse(center_lat_ > 0.0, xy.x(), xy.y(), lat_deg, lon_deg, gamma, k);
      out.lat = PlanetocentricFromPlanetographic(body_, RadFromDeg(lat_deg));
      out.lon = center_lon_ + RadFromDeg(lon_deg);
      break;
    }
  }
  out.lon = WrapLongitude(out.lon, LongitudeDomain::kPlusMinus180);
  return out;
}

std::string MapProjection::Wkt() const {
  switch (type_) {
    case ProjectionType::kEquirectangular:
      return ProjectedCrsWkt(surface_, "Equirectangular",
                             {{"center_lat", center_lat_}, {"center_lon", center_lon_}});
    case ProjectionType::kSinusoidal:
      return ProjectedCrsWkt(surface_, "Sinusoidal", {{"center_lon", center_lon_}});
    case ProjectionType::kPolarStereographic:
      return ProjectedCrsWkt(surface_, "PolarStereographic",
                             {{"center_lat", center_lat_}, {"center_lon", center_lon_}});
  }
  return {};
}

}  // namespace areomap
