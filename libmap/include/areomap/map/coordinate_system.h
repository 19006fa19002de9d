// Named coordinate systems for converting point lists (what `areomap coords` reads), all
// connected through Mars body-fixed XYZ (MBF), which is exact across bodies and CRSs.
//
// Specs (case-sensitive):
//   mbf                                X Y Z [m]
//   planetocentric[,west][,360]        lat lon [h]: degrees, h [m] above the body's ellipsoid
//   planetographic[,west][,360]        same, planetographic latitude (ISIS/MOC style with west)
//   spherical                          lat lon radius: planetocentric of the point itself, [m]
//   enu | site                         local frame at the origin (x y z [m]); site = MER site
//                                      frame (x north, y east, z down)
//   raster:PATH                        x y [h] map coordinates in PATH's CRS
//   pixel:PATH                         col row [h] pixel coordinates of PATH (centre = +0.5)
//   anything else                      a CRS GDAL/PROJ knows, e.g. IAU_2015:49910, in
//                                      traditional GIS order (x/lon first), degrees/metres
// ",west" means longitude positive west; ",360" writes longitudes in [0, 360) (input may be in
// either domain). Heights default to 0 when a line omits them.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <Eigen/Core>

#include "areomap/map/body.h"
#include "areomap/map/geodesy.h"

namespace areomap {

struct CoordinateSystemContext {
  Body body = Body::Mars2000();  // For the geographic and local systems.
  // Origin of enu/site frames: planetocentric latitude, east longitude [rad], h [m].
  std::optional<Geographic> origin;
};

class CoordinateSystem {
 public:
  // Throws areomap::Error for an unknown spec, an unreadable raster, a non-Mars CRS, or a
  // local frame without an origin.
  static CoordinateSystem Parse(std::string_view spec, const CoordinateSystemContext& context);
  ~CoordinateSystem();
  CoordinateSystem(CoordinateSystem&&) noexcept;
  CoordinateSystem& operator=(CoordinateSystem&&) noexcept;

  // Converts one input triple to MBF. Throws areomap::Error with a message naming the value
  // and the rule it broke (latitude outside [-90, 90], NaN, outside the projection).
  Eigen::Vector3d ToMbf(const Eigen::Vector3d& value) const;
  // Converts MBF to this system. Throws areomap::Error if the point cannot be represented.
  Eigen::Vector3d FromMbf(const Eigen::Vector3d& p_in_mbf) const;
  // printf-style precision per component for output (degrees get 12 decimals, metres 6).
  int Decimals(int component) const;
  // The body of the CRS's datum (ellipsoid or sphere radii) for raster:, pixel: and CRS
  // systems; nullopt for the others (they use the context's body).
  std::optional<Body> DatumBody() const;
  // Whether the context's body shapes this system (geographic and local systems).
  bool UsesBody() const;
  const std::string& spec() const { return spec_; }

 private:
  struct Impl;
  CoordinateSystem(std::unique_ptr<Impl> impl, std::string spec);
  std::unique_ptr<Impl> impl_;
  std::string spec_;
};

// The two systems `areomap coords --from --to` converts between (and the Python module's
// convert()). Without `body_given`, geographic and local systems take the datum of a raster:,
// pixel: or CRS system on the other side (`from`'s first), so that a raster's pixels come out in
// the latitudes its own CRS (and `info`) gives; `datum_body` then says which body that was and
// `datum_source` the spec it came from. With `body_given`, or when no side has a datum or no side
// uses the body, `context.body` stays and datum_body is nullopt. Throws as
// CoordinateSystem::Parse.
struct CoordinateConversion {
  CoordinateSystem from;
  CoordinateSystem to;
  std::optional<Body> datum_body;
  std::string datum_source;

  static CoordinateConversion Make(std::string_view from_spec, std::string_view to_spec,
                                   CoordinateSystemContext context, bool body_given);
  // to.FromMbf(from.ToMbf(value)); throws as they do.
  Eigen::Vector3d Convert(const Eigen::Vector3d& value) const;
};

// One point of a point list (`areomap coords` stdin and --origin, `areomap camera project` stdin):
// `min_numbers` (2 or 3) to 3 numbers separated by blanks, tabs or commas; `#` starts a comment;
// a missing third number is 0. Throws areomap::Error naming the token that is not a number, or
// the count when it is outside [min_numbers, 3] (extra tokens are an error, never ignored).
// Values are returned as written (they may be inf or NaN; ToMbf rejects those).
Eigen::Vector3d ParsePointLine(const std::string& line, int min_numbers = 2);

// True when a point-list line holds nothing but blanks, separators and a `#` comment: a line
// that readers skip rather than pass to ParsePointLine.
bool PointLineIsEmpty(const std::string& line);

}  // namespace areomap
