// Test scenes for crater detection: an orbital image rendered from a generated scene, with the
// scene's craters converted to image pixels (GDAL convention) as truth.
#pragma once

#include <cmath>
#include <vector>

#include "areomap/crater/ellipse.h"
#include "areomap/map/geodesy.h"
#include "areomap/samples/orbital.h"
#include "areomap/samples/scene.h"

namespace areomap::testing {

struct CraterScene {
  OrbitalProducts products;
  std::vector<Ellipse> truth_px;      // rim crests in image pixels
  std::vector<Ellipse> truth_dtm_px;  // rim crests in DTM pixels
  std::vector<Crater> craters;        // the scene's craters (ENU metres)
};

// ENU point (x east, y north) [m] -> map coordinates of the scene's projection, as the renderer
// maps pixels to ground (along the radial line through the projected lat/lon).
inline Eigen::Vector2d MapFromEnu(const SceneGeoreference& georef, const Eigen::Vector2d& enu) {
  const Eigen::Vector3d mbf = georef.EnuFromMbf().Inverse() * Eigen::Vector3d(enu.x(), enu.y(), 0);
  const Spherical s = SphericalFromMbf(mbf);
  return georef.Projection().Forward({s.lat, s.lon, 0.0});
}

inline Ellipse PixelEllipse(const SceneGeoreference& georef, const GeoTransform& gt,
                            const Crater& c) {
  const auto to_px = [&](const Eigen::Vector2d& enu) {
    const Eigen::Vector2d map = MapFromEnu(georef, enu);
    return gt.MapToPixel(map.x(), map.y());
  };
  const Eigen::Vector2d major(std::cos(c.angle), std::sin(c.angle));
  const Eigen::Vector2d minor(-std::sin(c.angle), std::cos(c.angle));
  const Eigen::Vector2d center = to_px(c.center);
  const Eigen::Vector2d a_end = to_px(c.center + c.semi_major * major);
  const Eigen::Vector2d b_end = to_px(c.center + c.semi_minor * minor);
  Ellipse e;
  e.center = center;
  e.semi_major = (a_end - center).norm();
  e.semi_minor = (b_end - center).norm();
  e.angle = WrapAxisAngle(std::atan2(a_end.y() - center.y(), a_end.x() - center.x()));
  return e.Normalized();
}

inline CraterScene MakeCraterScene(const SceneOptions& scene_options,
                                   const OrbitalImageOptions& image_options, double dtm_posting_m) {
  const Scene scene(scene_options);
  SceneGeoreference georef;
  georef.origin = {RadFromDeg(-2.05), RadFromDeg(354.5), -1900.0};
  CraterScene out;
  out.products = RenderOrbitalProducts(scene, georef, scene_options.half_extent_m, dtm_posting_m,
                                       image_options);
  out.craters = scene.craters();
  for (const Crater& c : scene.craters()) {
    out.truth_px.push_back(PixelEllipse(georef, out.products.image.geotransform, c));
    out.truth_dtm_px.push_back(PixelEllipse(georef, out.products.dtm.geotransform, c));
  }
  return out;
}

// The crater tests' field: 800 x 800 px at 0.5 m/px, 24 craters of 5-80 m (10-160 px), seed 7,
// lit from `sun_azimuth_deg` 30 degrees high.
inline CraterScene MakeFieldScene(double sun_azimuth_deg) {
  SceneOptions s;
  s.half_extent_m = 200.0;
  s.crater_count = 24;
  s.crater_min_diameter_m = 5.0;
  s.crater_max_diameter_m = 80.0;
  s.seed = 7;
  OrbitalImageOptions o;
  o.gsd_m = 0.5;
  o.sun_azimuth_deg = sun_azimuth_deg;
  o.sun_elevation_deg = 30.0;
  o.supersample = 1;
  return MakeCraterScene(s, o, 1.0);
}

}  // namespace areomap::testing
