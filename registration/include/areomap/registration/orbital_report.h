// What an orbital registration hands on: control points for the bundle adjustment
// (landmark_links.h ControlPoint, with the pixel and geographic detail a user checks), the
// orthophoto's corrected georeference, and pictures (the correlation surface).
//
// Frames: MBF is Mars body-fixed Cartesian on the orbital CRS's body [m]; ENU is the local
// level frame at each point; the site frame is MER SITE_FRAME (x north, y east, z down) of
// the ortho's site at its telemetry origin. Geographic output is planetocentric latitude,
// east longitude [rad in the structs, deg in JSON/CSV] and height above the ellipsoid [m].
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "areomap/map/landmark_links.h"
#include "areomap/registration/orbital_image.h"
#include "areomap/registration/orbital_match.h"

namespace areomap {

struct ControlPointOptions {
  double spacing_m = 10.0;   // Grid spacing of control points over the valid template [m], > 0.
  double dtm_sigma_m = 1.0;  // 1-sigma of heights read from the orbital DTM [m], > 0.
  // Without a DTM the height is the prior's, with this 1-sigma [m] (a 2D control point).
  double no_dtm_sigma_m = 50.0;
  // 1-sigma of a control point's position in its site frame [m], > 0: where the ortho cell is
  // (its grid position is exact; resampling places content within a cell, GSD / sqrt(12) for
  // the 0.25 m orthophotos of `run`). Independent from point to point. Stereo errors of the
  // ortho's content are not here: they are part of the match's shift, shared by all points.
  double site_sigma_m = 0.075;

  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

// A control point with the pixel and geographic detail behind it.
struct OrbitalControlPoint {
  ControlPoint point;          // The hand-off to the bundle adjustment.
  Eigen::Vector2d ortho_px;    // OrthoImage pixel (GDAL convention).
  Eigen::Vector2d orbital_px;  // Orbital pixel where the correction puts it.
  Geographic geographic;       // Planetocentric lat, east lon [rad], h [m] (corrected).
  double sigma_east_m = 0.0;
  double sigma_north_m = 0.0;
  double sigma_up_m = 0.0;
  bool height_from_dtm = false;
  // The match's probability of being a chance alignment (OrbitalMatch::false_match_probability),
  // shared by all its points.
  double false_match_probability = 1.0;
};

// Control points on a grid over the valid template pixels of a confident `match` (an empty
// list otherwise). Heights come from `dtm` (any Mars raster of heights above the ellipsoid)
// where given and defined, else from the prior. All points share one shift estimate, so their
// horizontal errors are one error, fully correlated: each point gets n times the match's shift
// covariance (n points), so that together they carry the shift's information once, not n times
// (sigma_east_m / sigma_north_m stay the match's own). The same holds for a low correlation's
// share of the rotation's error (OrbitalMatch::low_correlation_rotation_sigma_rad), which moves
// each point across its offset from OrbitalMatch::rotation_pivot_px; the rest of the rotation's
// error the points' spread conveys to the adjustment. Throws areomap::Error if the options fail
// Check() or a CRS is not on Mars.
std::vector<OrbitalControlPoint> MakeControlPoints(const OrbitalMatch& match,
                                                   const OrthoImage& ortho,
                                                   const OrbitalImage& orbital,
                                                   const OrbitalPrior& prior,
                                                   const std::optional<OrbitalImage>& dtm,
                                                   const ControlPointOptions& options = {});

// JSON array / CSV table of control points (degrees for angles, metres, covariances in m^2).
nlohmann::json ControlPointsJson(const std::vector<OrbitalControlPoint>& points);
std::string ControlPointsCsv(const std::vector<OrbitalControlPoint>& points);

// The match as JSON (verdict, shift in px and m with 1-sigma, rotation, scale, confidence).
nlohmann::json MatchJson(const OrbitalMatch& match);

// The orthophoto's geotransform corrected by `match` (in the ortho's own CRS): an affine
// least-squares fit of ortho pixel -> corrected map position over a grid of ortho pixels
// (exact when both CRSs are the same). Throws areomap::Error if a CRS is not on Mars or the
// grid cannot be mapped.
GeoTransform CorrectedGeoTransform(const OrbitalMatch& match, const OrthoImage& ortho,
                                   const OrbitalImage& orbital);

// The coarse correlation surface as an RGB picture (viridis, NaN black), enlarged `zoom`
// times, with the chosen peak marked.
cv::Mat CorrelationSurfaceImage(const OrbitalMatch& match, int zoom = 4);

}  // namespace areomap
