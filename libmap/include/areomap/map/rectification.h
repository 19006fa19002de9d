// Epipolar rectification of a stereo pair of any camera models (CAHV, CAHVOR, CAHVORE, pinhole).
//
// Like JPL's cmod_cahv_warp_models: both cameras are replaced by CAHV models that share A, H and
// V and keep their own centres C, with H along the baseline. Then epipolar lines are image rows,
// a point's disparity is x_left - x_right >= 0 (zero at infinity), and range follows from
// b f / disparity. The shared axis is the mean of the two cameras' linearized axes made
// perpendicular to the baseline; the scales are the mean of the two JPL linearizations
// (camera_linearize.h) for the output size; the principal point is the output centre.
//
// Frames: both input models in one frame (e.g. ROVER_FRAME); the rectified models are in it too.
// Pixels: first pixel centre at (0, 0). CAHVORE's moving entrance pupil is neglected in the
// remap (rays are projected from 1 km away), which is exact for central models.
//
// Failure: throws areomap::Error when the sizes are not positive, the centres coincide, the
// right camera is not to the right of the left one (a swapped pair), or the two rectified views
// share less than `min_overlap_fraction` of their pixels at infinity (no overlap).
#pragma once

#include <utility>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/map/cahvor.h"
#include "areomap/map/camera_models.h"

namespace areomap {

// A small correction of the pair's relative orientation (a real calibration's error), in the
// models' frame: the right camera's rays are turned by `right_rotation` (the direction the right
// model gives for a pixel, rotated, is where that pixel really looks), and the baseline (right
// centre minus left centre, length kept) by `baseline_rotation`. Identity: the models as given.
struct RectificationCorrection {
  Eigen::Matrix3d right_rotation = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d baseline_rotation = Eigen::Matrix3d::Identity();
};

struct RectificationOptions {
  Eigen::Vector2i output_size = Eigen::Vector2i::Zero();  // [px]; zero: the input size.
  double min_overlap_fraction = 0.02;  // Of the output pixels seen by both at infinity.
  RectificationCorrection correction;  // Applied to the right model and the baseline.
  void Check() const;                  // Throws areomap::Error naming the field.
};

struct StereoRectification {
  CahvorModel left, right;                         // Common CAHV pair (same A, H, V; own C).
  Eigen::Vector2i size = Eigen::Vector2i::Zero();  // Rectified image size (width, height).
  // For each rectified pixel, the input pixel it samples (CV_32F; -1 where it falls outside the
  // input image). Ready for cv::remap.
  cv::Mat left_map_x, left_map_y, right_map_x, right_map_y;
  double baseline_m = 0.0;
  double focal_px = 0.0;          // Horizontal scale of the common CAHV [px].
  double overlap_fraction = 0.0;  // Rectified pixels inside both input images at infinity.
};

StereoRectification RectifyStereoPair(const CameraModel& left, const CameraModel& right,
                                      const Eigen::Vector2i& input_size,
                                      const RectificationOptions& options);

// Relative-orientation correction from point correspondences between the rectified pair of
// `rect` (rectified pixels, left and right): the baseline's direction (2 angles) and the right
// camera's rotation (3 angles) that bring every correspondence to one row, by iteratively
// reweighted Gauss-Newton (Huber weights at 1 px; pairs off by more than 5 px after the first
// iteration are dropped). A baseline tilt makes the vertical disparity grow with the horizontal
// one, a rotation does not, so points at several depths are needed to tell them apart; a small
// damping keeps unobservable angles at zero. The correction composes with the one `rect` was
// built with. `rms_before_px` / `rms_after_px` receive the inliers' vertical disparity.
// Failure: throws areomap::Error with fewer than 20 correspondences.
struct RectificationFit {
  RectificationCorrection correction;
  double rms_before_px = 0.0, rms_after_px = 0.0;
  double right_rotation_deg = 0.0, baseline_tilt_deg = 0.0;
  size_t inliers = 0;
};
RectificationFit EstimateRectificationCorrection(
    const StereoRectification& rect, const RectificationCorrection& current,
    const std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>>& left_right_pixels);

// Resamples `image` (any depth, 1 channel) onto the rectified grid (bilinear; 0 outside).
cv::Mat RemapToRectified(const cv::Mat& image, const cv::Mat& map_x, const cv::Mat& map_y);

}  // namespace areomap
