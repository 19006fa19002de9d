// The planet as a parameter: a biaxial ellipsoid (or sphere) given by its radii.
//
// Every conversion takes a Body; no formula hard-codes a radius (STYLE.md #4).
// Units: metres.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace areomap {

struct Body {
  std::string name = "Mars2000";
  double a = 3396190.0;  // Equatorial radius [m].
  double b = 3376200.0;  // Polar radius [m].

  // IAU 2000 Mars ellipsoid (a = 3396190 m, b = 3376200 m); the default.
  static Body Mars2000();
  // IAU Mars sphere, R = 3396190 m (base of the IAU_2015:49900 CRS family).
  static Body MarsSphere();
  // MOLA reference sphere, R = 3396000 m.
  static Body MolaSphere();
  // A sphere of any radius, e.g. the local radius HiRISE RDR labels use.
  static Body Sphere(double radius, std::string name = "sphere");

  // Looks up "mars2000", "mars-sphere" or "mola-sphere" (case-insensitive).
  // Throws areomap::Error naming the accepted names otherwise.
  static Body FromName(std::string_view name);
  static std::vector<std::string> Names();

  double Flattening() const { return (a - b) / a; }
  double InverseFlattening() const;  // 0 for a sphere (GDAL/OGR convention).
  bool IsSphere() const { return a == b; }
  // Geocentric radius of the ellipsoid surface at planetocentric latitude `lat_c` [rad].
  double RadiusAtPlanetocentricLatitude(double lat_c) const;

  // Throws areomap::Error if a or b is not finite and positive or b > a.
  void Check() const;
};

bool operator==(const Body& lhs, const Body& rhs);

}  // namespace areomap
