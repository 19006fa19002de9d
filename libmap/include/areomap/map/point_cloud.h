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

}  // namespace areomap
