// Georeferencing rover sites: where a MER site frame sits on Mars and how its points are placed
// on a map.
//
// Frames: a site frame is the MER SITE_FRAME (x north, y east, z down [m]), level at its origin
// on the ground. MBF is Mars body-fixed Cartesian [m]. Map coordinates are (x, y) [m] in a
// projected CRS and z, the height above the body's ellipsoid [m] (what orbital DTMs store).
//
// Conventions: the local map of a site or mission is equirectangular on the sphere whose radius
// is the ellipsoid's local radius at the centre latitude, centred there (the HiRISE RDR
// convention, which the generator's orbital products follow). As in ISIS, a map-projected point's
// (x, y) come from the planetocentric latitude and longitude of its own radial line, so a rover
// map and an orbital map of the same ground overlay exactly. Any other Mars CRS can be asked for
// (MapFrame::FromCrs); PROJ then decides where (x, y) are, along the CRS's own normal line.
//
// Geodesy is libmap's (geodesy.h, projection.h, crs.h: GeographicLib and PROJ); nothing here
// re-derives it.
#pragma once

#include <memory>
#include <string>

#include <Eigen/Core>

#include "areomap/map/body.h"
#include "areomap/map/crs.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/projection.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

// Where one site frame sits on Mars.
struct SiteGeoreference {
  Body body = Body::Mars2000();
  Rigid3d mbf_from_site;  // Site frame -> MBF.

  // A site whose origin is at `origin` (planetocentric latitude, east longitude [rad], height
  // above the ellipsoid [m]), its frame level there (geodesy.h SiteFromMbf).
  static SiteGeoreference AtOrigin(const Body& body, const Geographic& origin);
  // A site given by its pose in a mission frame (the site frame of the mission origin, e.g.
  // site 0, located at `mission_origin`), as telemetry or a bundle adjustment gives it:
  // `mission_from_site` maps the site's frame into the mission origin's frame.
  static SiteGeoreference InMission(const Body& body, const Geographic& mission_origin,
                                    const Rigid3d& mission_from_site);

  // Planetocentric latitude, east longitude [rad] and height [m] of the site origin.
  Geographic Origin() const;
};

// How points are placed on a map. Cheap to copy (shared state); safe to use from many threads.
class MapFrame {
 public:
  // Equirectangular on the local-radius sphere at `center` (planetocentric latitude, east
  // longitude [rad]; h ignored), radial-line convention (see above).
  static MapFrame LocalEquirectangular(const Body& body, const Geographic& center);
  // Any projected Mars CRS PROJ knows (e.g. "IAU_2015:49910", a WKT). Heights stay above
  // `body`'s ellipsoid. Throws areomap::Error naming the CRS if it is not a projected Mars CRS.
  static MapFrame FromCrs(const Body& body, const Crs& crs);

  // MBF [m] -> (x, y) [m], z = height above the body's ellipsoid [m]. NaNs where the CRS cannot
  // map the point; never throws.
  Eigen::Vector3d MapFromMbf(const Eigen::Vector3d& p_in_mbf) const;
  // Inverse of MapFromMbf: the point at height z on the line of constant (x, y). NaNs where the
  // CRS cannot map it; never throws.
  Eigen::Vector3d MbfFromMap(const Eigen::Vector3d& p_in_map) const;

  // The map axes at a point: d(map)/d(MBF), the 3x3 Jacobian by central differences over 1 m,
  // used to carry covariances from MBF onto the map.
  Eigen::Matrix3d JacobianAt(const Eigen::Vector3d& p_in_mbf) const;

  const std::string& Wkt() const;  // WKT2 of the projected CRS, for GeoTIFFs.
  const Body& body() const;

 private:
  struct Impl;
  explicit MapFrame(std::shared_ptr<const Impl> impl) : impl_(std::move(impl)) {}
  std::shared_ptr<const Impl> impl_;
};

}  // namespace areomap
