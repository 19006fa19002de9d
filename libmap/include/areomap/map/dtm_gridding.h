// Gridding scattered 3D points into a raster DTM: TIN linear interpolation (CGAL 2D Delaunay)
// with a longest-edge limit so gaps are not bridged, and the mean, max and inverse-distance
// modes; besides the elevation, layers of point count, standard deviation and propagated 1 sigma.
//
// Frame and units: points and grid share one map frame, (x, y) [m] east/north-ish map axes and
// z [m] up (site_georeference.h MapFrame gives it). Covariances are in the same frame [m^2].
// Cells are north-up: cell (col, row) is centred at (x_left + (col + 0.5) posting,
// y_top - (row + 0.5) posting) (GDAL convention). Unknown cells are NaN in every Float32 layer
// and 0 in the count.
//
// Layers:
// - elevation: TIN: the plane of the Delaunay triangle holding the cell centre; mean/max: the
//   mean/highest z of the points falling in the cell; inverse distance: sum(w z) / sum(w),
//   w = 1 / d^power over the `idw_max_points` nearest points within `idw_radius_m` of the centre
//   (gdal_grid's invdistnn), a point closer than ~3e-7 m taking the cell as gdal_grid does.
// - count: points falling in the cell (whatever the method).
// - stddev: sample standard deviation of those points' z (NaN below 2 points).
// - sigma: the elevation's 1 sigma propagated from the points' covariances, taken independent:
//   sqrt(a^T (sum w_i^2 C_i) a) for the interpolation weights w_i (barycentric, 1/n, 1 for the
//   max, or IDW) and a = (-gx, -gy, 1): the height error at fixed (x, y) on a surface of
//   gradient g, so the along-slope part of a far point's range error counts. g is the gradient
//   of the elevation smoothed over `slope_baseline_m` (one triangle's own gradient is mostly
//   the points' noise where they are dense). It describes the measurement noise only, not the
//   interpolation error of relief the points do not resolve.
//
// Failure: invalid options or grids throw areomap::Error naming the field; points with a
// non-finite coordinate throw (callers check clouds first, point_cloud.h). Points outside the
// grid are ignored.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/map/progress.h"
#include "areomap/map/raster.h"

namespace areomap {

enum class GriddingMethod { kTin, kMean, kMax, kInverseDistance };
std::string ToString(GriddingMethod method);                     // "tin", "mean", "max", "idw"
GriddingMethod GriddingMethodFromString(std::string_view text);  // Throws areomap::Error.

// A north-up grid of square cells.
struct GridSpec {
  double x_left = 0.0;   // West edge [m].
  double y_top = 0.0;    // North edge [m].
  double posting = 1.0;  // Cell size [m].
  int width = 0;
  int height = 0;

  // The smallest grid with cell edges on multiples of `posting` covering [min, max] (x, y).
  static GridSpec Covering(const Eigen::Vector2d& min, const Eigen::Vector2d& max, double posting);
  GeoTransform Transform() const;
  // The window of this grid (same posting, aligned) holding the cells that meet [min, max],
  // or std::nullopt if none does.
  std::optional<GridSpec> Window(const Eigen::Vector2d& min, const Eigen::Vector2d& max) const;
  // (col, row) of this grid's first cell in `parent`, which it must be a window of; throws
  // areomap::Error otherwise.
  Eigen::Vector2i OffsetIn(const GridSpec& parent) const;
  Eigen::Vector2d CellCenter(int col, int row) const;
  void Check() const;  // Throws areomap::Error naming the field.
};

struct GridPoint {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();         // Map frame [m].
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // [m^2] in the map frame.
};

struct GriddingOptions {
  GriddingMethod method = GriddingMethod::kTin;
  // TIN: a triangle with an edge longer than max(max_edge_m, max_edge_per_range * range) is a
  // gap and left unknown; range is the horizontal distance from `viewpoint` (the camera, on the
  // map) to the triangle's centroid, since stereo points thin out with range (r^2 radially).
  double max_edge_m = 1.0;                              // [m]
  double max_edge_per_range = 0.0;                      // [m/m], 0: a fixed limit.
  Eigen::Vector2d viewpoint = Eigen::Vector2d::Zero();  // Map (x, y) [m].
  double idw_radius_m = 0.3;                            // Inverse distance: search radius [m].
  double idw_power = 2.0;                               // Inverse distance: weight exponent.
  int idw_max_points = 12;        // Inverse distance: nearest points used (gdal_grid default).
  double slope_baseline_m = 0.5;  // Sigma: terrain slope from the elevation smoothed over it [m].
  bool compute_sigma = true;      // Propagate covariances into the sigma layer.
  void Check() const;             // Throws areomap::Error naming the field.
};

// Float32 layers on one grid (count is Int32).
struct GriddedLayers {
  GridSpec grid;
  cv::Mat elevation;  // [m], NaN where unknown.
  cv::Mat count;      // Points in the cell.
  cv::Mat stddev;     // [m], NaN below 2 points.
  cv::Mat sigma;      // [m], NaN where unknown (or everywhere if !compute_sigma).
  int known_cells = 0;
};

// Grids `points` on `grid`. Parallel (TBB). `progress` may cancel (throws areomap::Error).
GriddedLayers GridPoints(const std::vector<GridPoint>& points, const GridSpec& grid,
                         const GriddingOptions& options,
                         const ProgressCallback& progress = nullptr);

}  // namespace areomap
