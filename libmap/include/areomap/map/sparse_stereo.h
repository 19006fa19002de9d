// Sparse stereo matching of single pixels along the epipolar curve of a calibrated CAHV/CAHVOR
// pair (ch. 2.2.2 tie points), with the fault-detection filters of Table 4.5: correlation
// >= 0.85, vertical disparity < 4 px, left->right->left consistency, intersection computable.
//
// Images are single-channel CV_8U or CV_32F (convert 12/16-bit frames once with convertTo) in
// JPL pixel convention (first pixel centre at (0, 0)); other types throw areomap::Error. Cameras
// are in one common frame. Failures are per pixel: the result says which filter rejected the match,
// nothing throws except Check() on bad options.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/map/cahvor.h"
#include "areomap/map/interest_points.h"

namespace areomap {

struct SparseStereoOptions {
  int half_window = 5;                     // Correlation window is (2 h + 1)^2 px.
  double min_range_m = 1.0;                // Search the left ray from here...
  double max_range_m = 60.0;               // ...to here (Table 4.5 keeps points within 30 m later).
  double disparity_step_px = 0.25;         // Sampling of the search along the curve.
  double min_correlation = 0.85;           // Table 4.5.
  double max_vertical_disparity_px = 4.0;  // Table 4.5.
  double max_back_match_px = 1.0;          // Left->right->left consistency.
  double min_texture = 1e-6;               // Minimum std of the left window (flat windows fail).
  void Check() const;                      // Throws areomap::Error naming the field.
};

struct SparseStereoMatch {
  bool ok = false;
  std::string rejected_by;  // Empty when ok; else the filter's name.
  Eigen::Vector2d right_pixel = Eigen::Vector2d::Zero();
  double correlation = 0.0;
  double vertical_disparity_px = 0.0;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  // Triangulated, in the cameras' frame.
  double range_m = 0.0;                             // From the left camera centre.
};

SparseStereoMatch MatchPixel(const cv::Mat& left, const cv::Mat& right,
                             const CahvorModel& left_camera, const CahvorModel& right_camera,
                             const Eigen::Vector2d& left_pixel,
                             const SparseStereoOptions& options = {});

// One interest point of the left image and what MatchPixel made of it (accepted or the filter
// that rejected it).
struct SparseTiePoint {
  InterestPoint left;
  SparseStereoMatch match;
};

// Stereo tie points as in ch. 2.2.2: every interest point (e.g. DetectForstnerPoints on `left`)
// matched along its epipolar curve with the Table 4.5 filters; one result per point, in order.
// Runs over the points in parallel (TBB).
std::vector<SparseTiePoint> MatchInterestPoints(const cv::Mat& left, const cv::Mat& right,
                                                const CahvorModel& left_camera,
                                                const CahvorModel& right_camera,
                                                const std::vector<InterestPoint>& points,
                                                const SparseStereoOptions& options = {});

}  // namespace areomap
