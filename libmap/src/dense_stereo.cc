#include "areomap/map/dense_stereo.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <tbb/parallel_for.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "areomap/map/error.h"
#include "areomap/map/report_progress.h"

namespace areomap {
namespace {

cv::Mat ToGrey(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat grey;
  cv::cvtColor(image, grey, image.channels() == 4 ? cv::COLOR_RGBA2GRAY : cv::COLOR_RGB2GRAY);
  return grey;
}

// The value below which 99.9 % of the valid (non-zero) pixels of both images lie.
double HighPercentile(const cv::Mat& a, const cv::Mat& b) {
  std::vector<float> values;
  for (const cv::Mat* m : {&a, &b}) {
    cv::Mat f;
    m->convertTo(f, CV_32F);
    for (int y = 0; y < f.rows; y += 3) {
      const float* row = f.ptr<float>(y);
      for (int x = 0; x < f.cols; x += 3) {
        if (row[x] > 0.0f) values.push_back(row[x]);
      }
    }
  }
  if (values.empty()) return 1.0;
  const size_t k = static_cast<size_t>(0.999 * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return std::max(1.0, static_cast<double>(values[k]));
}

// Corners tracked from left to right (pyramidal Lucas-Kanade with a forward-backward check), as
// (left pixel, right pixel) pairs.
using PixelPairs = std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>>;

PixelPairs TrackCorners(const cv::Mat& left8, const cv::Mat& right8, int cells) {
  std::vector<cv::Point2f> left_points, right_points, back_points;
  for (int cy = 0; cy < cells; ++cy) {  // The best corners of each cell, spread over the image.
    for (int cx = 0; cx < cells; ++cx) {
      const cv::Rect cell(cx * left8.cols / cells, cy * left8.rows / cells, left8.cols / cells,
                          left8.rows / cells);
      std::vector<cv::Point2f> corners;
      cv::goodFeaturesToTrack(left8(cell), corners, 40, 0.02, 10.0);
      for (const cv::Point2f& p : corners) {
        left_points.emplace_back(p.x + static_cast<float>(cell.x),
                                 p.y + static_cast<float>(cell.y));
      }
    }
  }
  PixelPairs out;
  if (left_points.empty()) return out;
  std::vector<uint8_t> status, back_status;
  std::vector<float> error;
  const cv::Size window(21, 21);
  const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
  cv::calcOpticalFlowPyrLK(left8, right8, left_points, right_points, status, error, window, 4,
                           stop);
  cv::calcOpticalFlowPyrLK(right8, left8, right_points, back_points, back_status, error, window, 4,
                           stop);
  for (size_t i = 0; i < left_points.size(); ++i) {
    if (!status[i] || !back_status[i] || cv::norm(back_points[i] - left_points[i]) > 0.5) continue;
    out.emplace_back(Eigen::Vector2d(left_points[i].x, left_points[i].y),
                     Eigen::Vector2d(right_points[i].x, right_points[i].y));
  }
  return out;
}

double Median(std::vector<double> values) {
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

// The right image's vertical offset field: the median vertical disparity of the tracked corners
// in each cell of a grid (cells with fewer than 5 take the global median), bilinearly
// interpolated between cell centres. Leaves `out` untouched with fewer than 20 corners.
constexpr double kMinRowShiftRmsPx = 0.5;

void EstimateRowShift(const cv::Mat& left8, const cv::Mat& right8, DisparityResult* out) {
  constexpr int kCells = 8;
  if (left8.cols < 8 * kCells || left8.rows < 8 * kCells) return;  // Too small to grid.
  std::vector<Eigen::Vector3d> tracks;                             // (x_right, y_right, dy).
  for (const auto& [l, r] : TrackCorners(left8, right8, kCells)) {
    tracks.emplace_back(r.x(), r.y(), r.y() - l.y());
  }
  if (tracks.size() < 20) return;
  std::vector<double> all;
  std::vector<std::vector<double>> per_cell(kCells * kCells);
  for (const Eigen::Vector3d& t : tracks) {
    const int cx = std::clamp(static_cast<int>(t.x() * kCells / left8.cols), 0, kCells - 1);
    const int cy = std::clamp(static_cast<int>(t.y() * kCells / left8.rows), 0, kCells - 1);
    per_cell[static_cast<size_t>(cy * kCells + cx)].push_back(t.z());
    all.push_back(t.z());
  }
  const double global = Median(all);
  cv::Mat cells(kCells, kCells, CV_32F);
  for (int i = 0; i < kCells * kCells; ++i) {
    const auto& v = per_cell[static_cast<size_t>(i)];
    cells.at<float>(i / kCells, i % kCells) =
        static_cast<float>(v.size() >= 5 ? Median(v) : global);
  }
  cv::resize(cells, out->row_shift, left8.size(), 0, 0, cv::INTER_LINEAR);
  double before = 0.0, after = 0.0;
  size_t inliers = 0;
  for (const Eigen::Vector3d& t : tracks) {
    const int x = std::clamp(static_cast<int>(std::lround(t.x())), 0, left8.cols - 1);
    const int y = std::clamp(static_cast<int>(std::lround(t.y())), 0, left8.rows - 1);
    const double residual = t.z() - out->row_shift.at<float>(y, x);
    if (std::abs(residual) > 3.0) continue;  // A wrong track, not a calibration residual.
    before += t.z() * t.z();
    after += residual * residual;
    ++inliers;
  }
  out->row_shift_features = inliers;
  if (inliers > 0) {
    out->row_shift_before_rms_px = std::sqrt(before / static_cast<double>(inliers));
    out->row_shift_rms_px = std::sqrt(after / static_cast<double>(inliers));
  }
  // Below half a pixel the rows already agree (SGBM's windows absorb it): no correction, so
  // tracking noise never moves a well-calibrated pair.
  if (inliers == 0 || out->row_shift_before_rms_px < kMinRowShiftRmsPx) {
    out->row_shift.release();
    out->row_shift_rms_px = out->row_shift_before_rms_px;
    out->row_shift_features = 0;
  }
}

// Real calibrations: when corners tracked on the rectified pair leave more than
// kMinRowShiftRmsPx of vertical disparity, the relative orientation (baseline direction, right
// camera rotation) fitted to them. Returns false (and leaves `out` alone) otherwise.
bool FitRelativeOrientation(const StereoRectification& rect, const cv::Mat& left8,
                            const cv::Mat& right8, DisparityResult* out,
                            RectificationCorrection* correction) {
  constexpr int kCells = 8;
  if (left8.cols < 8 * kCells || left8.rows < 8 * kCells) return false;  // Too small to grid.
  const PixelPairs tracks = TrackCorners(left8, right8, kCells);
  if (tracks.size() < 20) return false;
  const RectificationFit fit = EstimateRectificationCorrection(rect, {}, tracks);
  if (fit.rms_before_px < kMinRowShiftRmsPx) return false;
  // A fit that does not help, or turns the geometry further than any calibration error would,
  // comes from wrong tracks: keep the models as given.
  constexpr double kMaxCorrectionDeg = 15.0;
  if (!(fit.rms_after_px < fit.rms_before_px) || fit.baseline_tilt_deg > kMaxCorrectionDeg ||
      fit.right_rotation_deg > kMaxCorrectionDeg) {
    return false;
  }
  *correction = fit.correction;
  out->orientation_features = fit.inliers;
  out->orientation_rms_before_px = fit.rms_before_px;
  out->orientation_rms_after_px = fit.rms_after_px;
  out->right_rotation_deg = fit.right_rotation_deg;
  out->baseline_tilt_deg = fit.baseline_tilt_deg;
  return true;
}

double RowShiftAt(const cv::Mat& row_shift, double x, int y) {
  if (row_shift.empty()) return 0.0;
  const int column = std::clamp(static_cast<int>(std::lround(x)), 0, row_shift.cols - 1);
  return row_shift.at<float>(y, column);
}

}  // namespace

void DenseStereoOptions::Check() const {
  RequireOption(min_range_m > 0.0, "DenseStereoOptions.min_range_m", "a positive range [m]");
  RequireOption(max_range_m > min_range_m, "DenseStereoOptions.max_range_m", "> min_range_m");
  RequireOption(block_size >= 3 && block_size <= 11 && block_size % 2 == 1,
                "DenseStereoOptions.block_size", "an odd window of 3..11 px");
  RequireOption(uniqueness_ratio >= 0 && uniqueness_ratio <= 100,
                "DenseStereoOptions.uniqueness_ratio", "0..100 %");
  RequireOption(speckle_window_px >= 0, "DenseStereoOptions.speckle_window_px", ">= 0 px");
  RequireOption(speckle_range_px >= 1, "DenseStereoOptions.speckle_range_px", ">= 1 px");
  RequireOption(lr_max_diff_px >= 0.0, "DenseStereoOptions.lr_max_diff_px", ">= 0 px");
  RequireOption(max_disparity_step_px >= 0.0, "DenseStereoOptions.max_disparity_step_px",
                ">= 0 px (0: no occlusion-edge filter)");
  RequireOption(occlusion_margin_px >= -1 && occlusion_margin_px <= 64,
                "DenseStereoOptions.occlusion_margin_px", "-1 (block_size / 2) or 0..64 px");
  RequireOption(disparity_margin_px >= 0 && disparity_margin_px % 16 == 0,
                "DenseStereoOptions.disparity_margin_px", "a multiple of 16 px, >= 0");
  RequireOption(output_size.minCoeff() >= 0, "DenseStereoOptions.output_size",
                "zero (the input size) or a positive width and height");
  RequireOption(parallax_sigma_px > 0.0, "DenseStereoOptions.parallax_sigma_px", "> 0 px");
  RequireOption(azimuth_sigma_px > 0.0, "DenseStereoOptions.azimuth_sigma_px", "> 0 px");
  line_of_sight.Check();
}

cv::Mat ComputeDisparity(const cv::Mat& left8, const cv::Mat& right8, int min_disparity,
                         int num_disparities, const DenseStereoOptions& options) {
  const int b = options.block_size;
  const cv::Ptr<cv::StereoSGBM> sgbm = cv::StereoSGBM::create(
      min_disparity, num_disparities, b, 8 * b * b, 32 * b * b, /*disp12MaxDiff=*/-1,
      /*preFilterCap=*/63, options.uniqueness_ratio, options.speckle_window_px,
      options.speckle_range_px, cv::StereoSGBM::MODE_SGBM_3WAY);
  // SGBM leaves the first min_disparity + num_disparities columns unmatched; padding both
  // images on the left by that much lets pixels near the border match (where x - d >= 0).
  const int pad = std::max(0, min_disparity + num_disparities);
  const auto match = [&](const cv::Mat& first, const cv::Mat& second) {
    cv::Mat a_padded, b_padded, disparity;
    cv::copyMakeBorder(first, a_padded, 0, 0, pad, 0, cv::BORDER_CONSTANT, cv::Scalar(0));
    cv::copyMakeBorder(second, b_padded, 0, 0, pad, 0, cv::BORDER_CONSTANT, cv::Scalar(0));
    sgbm->compute(a_padded, b_padded, disparity);  // CV_16S, 1/16 px.
    return cv::Mat(disparity, cv::Rect(pad, 0, first.cols, first.rows)).clone();
  };
  const cv::Mat left_disparity = match(left8, right8);
  // The right image's disparity: the same matcher on the pair turned by 180 degrees (mirrored
  // and upside down). SGBM_3WAY aggregates along paths from the rows above only, which pulls
  // disparities toward those of the rows above (on ground seen from a mast: smaller, ranges too
  // long); upside down, the pull comes from below. The average of the two runs cancels it.
  cv::Mat left_turned, right_turned, right_disparity;
  cv::flip(left8, left_turned, -1);
  cv::flip(right8, right_turned, -1);
  cv::flip(match(right_turned, left_turned), right_disparity, -1);

  cv::Mat out(left8.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  const float tolerance = static_cast<float>(options.lr_max_diff_px);
  const int invalid_below = 16 * min_disparity;
  tbb::parallel_for(0, out.rows, [&](int y) {
    const int16_t* dl = left_disparity.ptr<int16_t>(y);
    const int16_t* dr = right_disparity.ptr<int16_t>(y);
    float* d = out.ptr<float>(y);
    for (int x = 0; x < out.cols; ++x) {
      if (dl[x] < invalid_below) continue;
      const float disparity = static_cast<float>(dl[x]) / 16.0f;
      const int xr = static_cast<int>(std::lround(static_cast<float>(x) - disparity));
      if (xr < 0 || xr >= out.cols || dr[xr] < invalid_below) continue;
      const float other = static_cast<float>(dr[xr]) / 16.0f;
      if (std::abs(disparity - other) <= tolerance) d[x] = 0.5f * (disparity + other);
    }
  });
  if (options.max_disparity_step_px > 0.0) {
    // Occlusion edges: a jump to a valid neighbour (right or below) larger than the step.
    cv::Mat jump(out.size(), CV_8U, cv::Scalar(0));
    const float step = static_cast<float>(options.max_disparity_step_px);
    tbb::parallel_for(0, out.rows, [&](int y) {
      const float* d = out.ptr<float>(y);
      const float* below = out.ptr<float>(std::min(y + 1, out.rows - 1));
      uint8_t* j = jump.ptr<uint8_t>(y);
      for (int x = 0; x < out.cols; ++x) {
        const float right = d[std::min(x + 1, out.cols - 1)];
        if (std::abs(d[x] - right) > step || std::abs(d[x] - below[x]) > step) j[x] = 255;
      }
    });  // Comparisons with NaN are false: invalid neighbours are not jumps.
    const int r =
        options.occlusion_margin_px >= 0 ? options.occlusion_margin_px : options.block_size / 2;
    cv::dilate(jump, jump,
               cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * r + 2, 2 * r + 2)));
    out.setTo(std::numeric_limits<float>::quiet_NaN(), jump);
  }
  return out;
}

namespace {

void CheckStereoPair(const cv::Mat& left_image, const cv::Mat& right_image, const CameraFile& left,
                     const CameraFile& right) {
  if (left_image.empty() || right_image.empty()) {
    throw Error("stereo pair: an image is empty (" + left.source + ", " + right.source + ")");
  }
  if (left_image.size() != right_image.size()) {
    throw Error("stereo pair: image sizes differ: " + std::to_string(left_image.cols) + "x" +
                std::to_string(left_image.rows) + " (left) vs " + std::to_string(right_image.cols) +
                "x" + std::to_string(right_image.rows) + " (right): expected the same size");
  }
  if (left.frame != right.frame) {
    throw Error("stereo pair: camera models in different frames: " + left.frame + " (" +
                left.source + ") vs " + right.frame + " (" + right.source + ")");
  }
  for (const CameraFile* file : {&left, &right}) {
    if (file->image_size &&
        *file->image_size != Eigen::Vector2i(left_image.cols, left_image.rows)) {
      throw Error(file->source + ": the label's image size " +
                  std::to_string(file->image_size->x()) + "x" +
                  std::to_string(file->image_size->y()) + " differs from the image's " +
                  std::to_string(left_image.cols) + "x" + std::to_string(left_image.rows));
    }
  }
}

// What later stages need of the rectification stage to resample the right image again.
struct RectifiedGrey {
  cv::Mat right_grey;  // The right input image, single channel.
  double gain = 0.0;   // From input DN to 8 bits.
};

// Rectifies the pair into result->rectification and the 8-bit images result->disparity.left8
// and right8; with options.align_rows, when tracked corners show the rows disagree, fits the
// relative orientation and rectifies again with it.
RectifiedGrey RectifyToEightBit(const cv::Mat& left_image, const cv::Mat& right_image,
                                const CameraFile& left, const CameraFile& right,
                                const DenseStereoOptions& options, DenseStereoResult* result) {
  RectificationOptions rect_options;
  rect_options.output_size = options.output_size;
  result->rectification =
      RectifyStereoPair(left.model, right.model, {left_image.cols, left_image.rows}, rect_options);
  const StereoRectification& rect = result->rectification;
  const cv::Mat left_grey = ToGrey(left_image), right_grey = ToGrey(right_image);
  DisparityResult& disparity = result->disparity;
  double gain = 0.0;  // One gain for both images: the 99.9th percentile of the first pair.
  const auto rectify_images = [&] {
    const cv::Mat left_rect = RemapToRectified(left_grey, rect.left_map_x, rect.left_map_y);
    const cv::Mat right_rect = RemapToRectified(right_grey, rect.right_map_x, rect.right_map_y);
    if (gain == 0.0) gain = 255.0 / HighPercentile(left_rect, right_rect);
    left_rect.convertTo(disparity.left8, CV_8U, gain);
    right_rect.convertTo(disparity.right8, CV_8U, gain);
  };
  rectify_images();
  if (options.align_rows && FitRelativeOrientation(rect, disparity.left8, disparity.right8,
                                                   &disparity, &rect_options.correction)) {
    result->rectification = RectifyStereoPair(left.model, right.model,
                                              {left_image.cols, left_image.rows}, rect_options);
    rectify_images();
  }
  return {right_grey, gain};
}

// The maps from rectified right pixel to input right pixel that matching uses.
struct RightMaps {
  cv::Mat x, y;
};

// The common right model's maps sampled at (x, y + row_shift(x, y)).
RightMaps ShiftRightMaps(const StereoRectification& rect, const cv::Mat& row_shift) {
  // Own buffers: cv::remap below must not write into the maps it reads (rect's).
  RightMaps maps{rect.right_map_x.clone(), rect.right_map_y.clone()};
  cv::Mat shift_x(rect.size.y(), rect.size.x(), CV_32F), shift_y(shift_x.size(), CV_32F);
  for (int y = 0; y < shift_x.rows; ++y) {
    for (int x = 0; x < shift_x.cols; ++x) {
      shift_x.at<float>(y, x) = static_cast<float>(x);
      shift_y.at<float>(y, x) = static_cast<float>(y) + row_shift.at<float>(y, x);
    }
  }
  cv::remap(rect.right_map_x, maps.x, shift_x, shift_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(-1));
  cv::remap(rect.right_map_y, maps.y, shift_x, shift_y, cv::INTER_NEAREST, cv::BORDER_CONSTANT,
            cv::Scalar(-1));
  // Interpolate the maps where both neighbours are inside; nearest keeps -1 borders intact.
  cv::Mat linear_x, linear_y;
  cv::remap(rect.right_map_x, linear_x, shift_x, shift_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar(-1));
  cv::remap(rect.right_map_y, linear_y, shift_x, shift_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar(-1));
  linear_x.copyTo(maps.x, (linear_x >= 0.0f) & (maps.x >= 0.0f));
  linear_y.copyTo(maps.y, (linear_x >= 0.0f) & (maps.x >= 0.0f));
  return maps;
}

// With options.align_rows, the right image's residual row shift (EstimateRowShift) and, when
// there is one, the right 8-bit image resampled through the shifted maps. Returns the maps
// matching uses.
RightMaps AlignRightRows(const cv::Mat& right_grey, const StereoRectification& rect, double gain,
                         const DenseStereoOptions& options, DisparityResult* disparity) {
  if (!options.align_rows) return {rect.right_map_x.clone(), rect.right_map_y.clone()};
  EstimateRowShift(disparity->left8, disparity->right8, disparity);
  if (disparity->row_shift_features == 0) {
    return {rect.right_map_x.clone(), rect.right_map_y.clone()};
  }
  const RightMaps maps = ShiftRightMaps(rect, disparity->row_shift);
  RemapToRectified(right_grey, maps.x, maps.y).convertTo(disparity->right8, CV_8U, gain);
  return maps;
}

// The disparity search range: from -disparity_margin_px to the disparity at min_range_m.
void SetDisparityRange(const StereoRectification& rect, const DenseStereoOptions& options,
                       DisparityResult* disparity) {
  const double max_disparity = rect.baseline_m * rect.focal_px / options.min_range_m;
  disparity->min_disparity = -options.disparity_margin_px;
  disparity->num_disparities = std::clamp(
      16 * static_cast<int>(std::ceil(max_disparity / 16.0)) + options.disparity_margin_px, 16,
      std::max(16, (rect.size.x() / 2) / 16 * 16));
}

// Matches the 8-bit pair into disparity->disparity and counts overlap and valid pixels; returns
// the overlap mask.
cv::Mat MatchPair(const RightMaps& right_maps, const DenseStereoOptions& options,
                  DisparityResult* disparity) {
  disparity->disparity =
      ComputeDisparity(disparity->left8, disparity->right8, disparity->min_disparity,
                       disparity->num_disparities, options);
  // Overlap: rectified left pixels whose right partner at infinity is inside the right image.
  const cv::Mat overlap = disparity->valid_left & (right_maps.x >= 0.0f);
  disparity->overlap_pixels = static_cast<size_t>(cv::countNonZero(overlap));
  const cv::Mat has_disparity = disparity->disparity == disparity->disparity;  // Not NaN.
  disparity->valid_pixels = static_cast<size_t>(cv::countNonZero(has_disparity & overlap));
  return overlap;
}

StereoErrorModel StereoErrorModelOf(const StereoRectification& rect,
                                    const DenseStereoOptions& options) {
  StereoErrorModel error_model;
  error_model.baseline_m = rect.baseline_m;
  error_model.focal_px = rect.focal_px;
  error_model.parallax_sigma_px = options.parallax_sigma_px;
  error_model.azimuth_sigma_px = options.azimuth_sigma_px;
  error_model.Check();
  return error_model;
}

// The frame the points are given in: the site frame when the left label places the camera
// frame in it, the camera models' frame otherwise.
struct OutputFrame {
  Rigid3d out_from_model;
  Eigen::Vector3d center_out;  // The left camera centre in that frame.
};

OutputFrame OutputFrameOf(const CameraFile& left, const StereoRectification& rect) {
  OutputFrame frame;
  frame.out_from_model = left.site_from_frame.value_or(Rigid3d());
  frame.center_out = frame.out_from_model * rect.left.c;
  return frame;
}

struct RowPoints {
  std::vector<StereoPoint> points, beyond;  // beyond: kept only as line-of-sight witnesses
  size_t beyond_count = 0, not_intersecting = 0;
};

// Triangulates every overlap pixel with a disparity, one image row per entry.
std::vector<RowPoints> TriangulateRows(const StereoRectification& rect,
                                       const DisparityResult& disparity, const cv::Mat& overlap,
                                       const OutputFrame& frame,
                                       const StereoErrorModel& error_model,
                                       const DenseStereoOptions& options) {
  std::vector<RowPoints> rows(static_cast<size_t>(rect.size.y()));
  tbb::parallel_for(0, rect.size.y(), [&](int y) {
    RowPoints& row = rows[static_cast<size_t>(y)];
    const float* d = disparity.disparity.ptr<float>(y);
    const uint8_t* in_overlap = overlap.ptr<uint8_t>(y);
    for (int x = 0; x < rect.size.x(); ++x) {
      if (!(d[x] == d[x]) || in_overlap[x] == 0) continue;
      const Eigen::Vector3d d1 = rect.left.Unproject(Eigen::Vector2d(x, y));
      const double xr = x - static_cast<double>(d[x]);
      const Eigen::Vector3d d2 =
          rect.right.Unproject(Eigen::Vector2d(xr, y + RowShiftAt(disparity.row_shift, xr, y)));
      const auto hit = TriangulateRays(rect.left.c, d1, rect.right.c, d2);
      if (!hit) {
        ++row.not_intersecting;
        continue;
      }
      const bool is_beyond = hit->range_first_m > options.max_range_m;
      if (is_beyond) {
        ++row.beyond_count;
        if (!options.check_line_of_sight) continue;
      }
      StereoPoint p;
      p.position = frame.out_from_model * hit->point;
      p.covariance = StereoPointCovariance(p.position, frame.center_out, error_model);
      p.intensity = static_cast<float>(disparity.left8.at<uint8_t>(y, x)) / 255.0f;
      p.left_x = rect.left_map_x.at<float>(y, x);
      p.left_y = rect.left_map_y.at<float>(y, x);
      p.image_id = options.image_id;
      // Points beyond max_range_m are dropped but still witness the line of sight.
      (is_beyond ? row.beyond : row.points).push_back(p);
    }
  });
  return rows;
}

// The rows' points, in row order, into result->cloud, then the line-of-sight check; the
// counts into result->summary.
void GatherPoints(const std::vector<RowPoints>& rows, const CameraFile& left,
                  const OutputFrame& frame, const DenseStereoOptions& options,
                  DenseStereoResult* result) {
  PointCloud& cloud = result->cloud;
  cloud.camera_center = frame.center_out;
  if (left.site_from_frame) {
    cloud.frame = "SITE_FRAME";
    cloud.site = left.site;
  } else {
    cloud.frame = left.frame;
    cloud.site = -1;
  }
  DenseStereoSummary& summary = result->summary;
  std::vector<StereoPoint> beyond;
  for (const RowPoints& row : rows) {
    cloud.points.insert(cloud.points.end(), row.points.begin(), row.points.end());
    beyond.insert(beyond.end(), row.beyond.begin(), row.beyond.end());
    summary.beyond_range += row.beyond_count;
    summary.not_intersecting += row.not_intersecting;
  }
  if (options.check_line_of_sight) {
    summary.line_of_sight = DropLineOfSightConflicts(&cloud, options.line_of_sight, beyond);
  }
}

// The rest of result->summary, from the disparity, the rectification and the cloud.
void SummarizeStereo(DenseStereoResult* result) {
  const DisparityResult& disparity = result->disparity;
  const StereoRectification& rect = result->rectification;
  DenseStereoSummary& summary = result->summary;
  summary.overlap_pixels = disparity.overlap_pixels;
  summary.valid_pixels = disparity.valid_pixels;
  summary.valid_fraction = disparity.overlap_pixels == 0
                               ? 0.0
                               : static_cast<double>(disparity.valid_pixels) /
                                     static_cast<double>(disparity.overlap_pixels);
  summary.points = result->cloud.points.size();
  summary.baseline_m = rect.baseline_m;
  summary.focal_px = rect.focal_px;
  summary.num_disparities = disparity.num_disparities;
}

}  // namespace

DenseStereoResult RunDenseStereo(const cv::Mat& left_image, const cv::Mat& right_image,
                                 const CameraFile& left, const CameraFile& right,
                                 const DenseStereoOptions& options,
                                 const ProgressCallback& progress) {
  options.Check();
  CheckStereoPair(left_image, right_image, left, right);
  DenseStereoResult result;
  ReportProgress(progress, 0.0, "stereo: rectify");
  const RectifiedGrey grey =
      RectifyToEightBit(left_image, right_image, left, right, options, &result);
  const StereoRectification& rect = result.rectification;
  DisparityResult& disparity = result.disparity;
  disparity.valid_left = rect.left_map_x >= 0.0f;
  const RightMaps right_maps =
      AlignRightRows(grey.right_grey, rect, grey.gain, options, &disparity);
  SetDisparityRange(rect, options, &disparity);

  ReportProgress(progress, 0.1, "stereo: match");
  const cv::Mat overlap = MatchPair(right_maps, options, &disparity);

  ReportProgress(progress, 0.8, "stereo: triangulate");
  const OutputFrame frame = OutputFrameOf(left, rect);
  const std::vector<RowPoints> rows =
      TriangulateRows(rect, disparity, overlap, frame, StereoErrorModelOf(rect, options), options);
  GatherPoints(rows, left, frame, options, &result);
  SummarizeStereo(&result);
  ReportProgress(progress, 1.0, "stereo: done");
  return result;
}

}  // namespace areomap
