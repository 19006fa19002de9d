// Stereo 3D points with their uncertainty: the hand-off from stereo to DTM gridding, rock
// extraction and tie-point selection.
//
// Frame: the cloud's `frame` names it. For rover data it is a site frame (MER SITE_FRAME: x north,
// y east, z down, metres), and `camera_center` is the left camera centre in that frame, so the
// range of a point is |position - camera_center|. Covariances are in m^2 in the same frame
// (eqs. 4.1-4.3 through StereoPointCovariance). A point with any non-finite coordinate is invalid;
// producers never emit one and consumers reject clouds that contain one (see CheckPointCloud).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace areomap {

struct StereoPoint {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();    // [m] in the cloud's frame.
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // [m^2] in the cloud's frame.
  float intensity = 0.0f;  // Left-image value at the pixel, scaled to [0, 1].
  float left_x = 0.0f;     // Left-image pixel (column, row), pixel centres at integers.
  float left_y = 0.0f;
  uint16_t image_id = 0;  // Which stereo pair of the site the point came from.
};

struct PointCloud {
  std::string frame = "SITE_FRAME";  // Free text, e.g. "SITE_FRAME site 3".
  int site = -1;                     // Site index when the frame is a site frame.
  Eigen::Vector3d camera_center = Eigen::Vector3d::Zero();  // Left camera centre [m].
  std::vector<StereoPoint> points;
};

// Throws areomap::Error naming `source` when the cloud is empty (if !allow_empty) or a point
// has a non-finite position or covariance.
void CheckPointCloud(const PointCloud& cloud, const std::string& source, bool allow_empty = false);

// Thins a stereo cloud so that near ground is not sampled far more densely than needed: a point
// at range r (from camera_center) is kept when its left pixel lies on a grid of step
// s = clamp(round(spacing_m f / r), 1, max_step) pixels, i.e. about one point per spacing_m of
// ground across the line of sight. `focal_px` is the camera's focal length [px]. Far points
// (whose pixel footprint r / f already exceeds spacing_m) are all kept.
PointCloud ThinToGroundSpacing(const PointCloud& cloud, double spacing_m, double focal_px,
                               int max_step = 8);

// Where stereo pairs of different precision see the same ground (a Pancam panorama over a Navcam
// one: at 20 m a Navcam point is ~4x less precise), keeps only the precise pairs' points there,
// so that rock peaks and planes are not taken from the noisier pair's points. The ground is cut
// into square cells of `cell_m` (x, y of the cloud's frame); in each cell, the points of each
// pair (`image_id`) that has at least `min_points` there are a source with the median of
// sqrt(trace covariance) as its sigma; a source whose sigma exceeds `sigma_ratio` x the cell's
// smallest is dropped from the cell (the smallest counts only among sources of at least
// `min_points` points; a sparser source sets no bar but is dropped like any other above it).
// A cell seen by one pair, or by pairs of like precision, keeps all. Order is preserved. Throws
// areomap::Error on a non-positive cell, a ratio below 1 or min_points < 1.
struct PreciseSourceOptions {
  double cell_m = 0.25;
  double sigma_ratio = 2.0;
  int min_points = 5;
  void Check() const;  // Throws areomap::Error naming the field.
};
PointCloud KeepMostPreciseSource(const PointCloud& cloud, const PreciseSourceOptions& options);

}  // namespace areomap
