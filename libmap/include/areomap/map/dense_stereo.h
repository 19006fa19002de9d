// Dense stereo: rectified pair → disparity (OpenCV's semi-global matcher) → 3D points with
// covariance (the stereo error model, eqs. 4.1-4.3) in the site frame.
//
// Steps: epipolar rectification (rectification.h); when corners tracked on it show more than
// 0.5 px of vertical disparity, the pair's relative orientation (baseline direction, right camera
// rotation) fitted to them and the rectification redone (unless the fit does not lower the
// vertical disparity or turns either by more than 15 degrees); a residual row alignment: sparse
// features (Shi-Tomasi corners tracked by pyramidal Lucas-Kanade, forward-backward checked) give
// the vertical offset of the right image, the median dy of each cell of an 8 x 8 grid,
// interpolated, applied when their RMS exceeds 0.5 px, shifts the right image's rows (real
// calibrations leave a few pixels, ASP's "affine epipolar" idea); SGBM on 8-bit images (both scaled
// by one gain: the 99.9th percentile of the pair); SGBM's own subpixel fit (1/16 px), uniqueness
// test and speckle filter; an explicit left-right consistency check against a second SGBM run on
// the pair turned by 180 degrees (|d_left(x) - d_right(x - d_left)| <= lr_max_diff_px), the
// disparity kept being the mean of the two (SGBM_3WAY's smoothness pulls each run toward the
// rows it aggregates from, above for one, below for the other: the mean cancels that bias, which
// made near ground ranges ~0.4 px of disparity too long); pixels near disparity
// jumps (occlusion edges) dropped; ray triangulation
// (TriangulateRays) of the rectified rays; points farther than max_range_m from the left camera are
// dropped, and so are points that contradict the line of sight (line_of_sight.h: buried under
// the ground seen in front of them, like the rover's own deck, or floating over the ground seen
// behind them; the frame's +z must point down).
//
// Frames: the two camera models must be in the same frame. When the left camera's file gives
// the frame's pose in a site frame (the MER / generator ROVER_COORDINATE_SYSTEM group) the cloud
// is in that SITE_FRAME; otherwise in the model frame (e.g. TSAI_WORLD for .tsai files).
// Units: metres, pixels (first pixel centre at (0, 0)).
//
// Failure: throws areomap::Error for mismatched image sizes, empty images, models in different
// frames, a pair with no overlap (RectifyStereoPair), bad options, or when `progress` returns
// false (cancelled). Colour images are converted to grey.
#pragma once

#include <cstddef>
#include <string>

#include <opencv2/core.hpp>

#include "areomap/map/camera_models.h"
#include "areomap/map/line_of_sight.h"
#include "areomap/map/point_cloud.h"
#include "areomap/map/progress.h"
#include "areomap/map/rectification.h"
#include "areomap/map/stereo_error.h"

namespace areomap {

struct DenseStereoOptions {
  double min_range_m = 1.0;     // Nearest range searched: sets SGBM's disparity range b f / r.
  double max_range_m = 30.0;    // Points beyond are dropped (Table 4.5: 30 m).
  int block_size = 5;           // SGBM matching window [px], odd, 3..11.
  int uniqueness_ratio = 10;    // SGBM uniqueness margin [%].
  int speckle_window_px = 100;  // Largest disparity blob removed as a speckle [px].
  int speckle_range_px = 2;     // Disparity variation within one blob [px].
  double lr_max_diff_px = 2.0;  // Left-right tolerance [px]: the two runs' opposite pulls can
                                // differ by ~1 px on steep near ground.
  double max_disparity_step_px = 2.0;  // Jumps larger than this between neighbours mark an
                                       // occlusion edge; pixels within occlusion_margin_px of one
                                       // are dropped (SGBM foreground fattening). 0: keep.
  int occlusion_margin_px = -1;  // Pixels dropped beside an occlusion edge; -1: block_size / 2.
  int disparity_margin_px = 16;  // Also searched below zero (calibration errors) [px].
  Eigen::Vector2i output_size = Eigen::Vector2i::Zero();  // Rectified size; zero: input size.
  double parallax_sigma_px = 0.5;                         // sigma_p of eq. 4.3 for the covariances.
  double azimuth_sigma_px = 1.0;                          // Across-track sigma [px] (ch. 4.1).
  bool align_rows = true;           // Estimate and remove the residual vertical disparity.
  bool check_line_of_sight = true;  // Drop the points line_of_sight.h condemns.
  LineOfSightOptions line_of_sight;
  uint16_t image_id = 0;  // Written into every point.
  void Check() const;     // Throws areomap::Error naming the field.
};

// The 8-bit rectified pair and its disparity (CV_32F on the rectified left grid, NaN where
// invalid). `valid_left` marks rectified left pixels that sample the input image.
struct DisparityResult {
  cv::Mat left8, right8, disparity, valid_left;
  int min_disparity = 0;
  int num_disparities = 0;
  // Right-image row shift applied before matching: right rectified pixel (x, y) shows what the
  // common CAHV right model sees at (x, y + row_shift(y, x)) (CV_32F [px]; empty: none).
  cv::Mat row_shift;
  size_t row_shift_features = 0;         // Features the fit used (0: no correction).
  double row_shift_rms_px = 0.0;         // Residual vertical disparity of those features.
  double row_shift_before_rms_px = 0.0;  // Their vertical disparity before the correction.
  // Relative orientation fitted to tracked corners (real calibrations: vertical disparity above
  // 0.5 px), the rectification redone with it (rectification.h); 0 features: not needed.
  size_t orientation_features = 0;
  double orientation_rms_before_px = 0.0, orientation_rms_after_px = 0.0;
  double right_rotation_deg = 0.0, baseline_tilt_deg = 0.0;
  size_t overlap_pixels = 0;  // Left pixels whose right partner at min disparity is inside.
  size_t valid_pixels = 0;    // Overlap pixels with a disparity after all filters.
};

struct DenseStereoSummary {
  size_t overlap_pixels = 0;
  size_t valid_pixels = 0;
  double valid_fraction = 0.0;  // valid_pixels / overlap_pixels.
  size_t points = 0;
  size_t beyond_range = 0;         // Triangulated but farther than max_range_m.
  LineOfSightDrops line_of_sight;  // Dropped by the line-of-sight check.
  size_t not_intersecting = 0;
  double baseline_m = 0.0;
  double focal_px = 0.0;
  int num_disparities = 0;
};

struct DenseStereoResult {
  StereoRectification rectification;
  DisparityResult disparity;
  PointCloud cloud;
  DenseStereoSummary summary;
};

// SGBM + left-right check on an already rectified 8-bit pair (used by RunDenseStereo; exposed for
// the benchmark and tests). Searches [min_disparity, min_disparity + num_disparities); returns
// CV_32F disparities [px] with NaN where invalid.
cv::Mat ComputeDisparity(const cv::Mat& left8, const cv::Mat& right8, int min_disparity,
                         int num_disparities, const DenseStereoOptions& options);

// Both images of the same size (8- or 16-bit); the files give the models.
DenseStereoResult RunDenseStereo(const cv::Mat& left_image, const cv::Mat& right_image,
                                 const CameraFile& left, const CameraFile& right,
                                 const DenseStereoOptions& options,
                                 const ProgressCallback& progress = nullptr);

}  // namespace areomap
