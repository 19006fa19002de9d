#include "areomap/map/sparse_stereo.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/stereo_error.h"

namespace areomap {
namespace {

cv::Mat Window(const cv::Mat& image, const Eigen::Vector2d& at, int half) {
  cv::Mat out;
  cv::getRectSubPix(image, cv::Size(2 * half + 1, 2 * half + 1),
                    cv::Point2f(static_cast<float>(at.x()), static_cast<float>(at.y())), out,
                    CV_32F);
  return out;
}

double Ncc(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat result;
  cv::matchTemplate(a, b, result, cv::TM_CCOEFF_NORMED);
  return static_cast<double>(result.at<float>(0, 0));
}

bool Inside(const cv::Mat& image, const Eigen::Vector2d& p, int half) {
  return p.x() >= half && p.y() >= half && p.x() <= image.cols - 1 - half &&
         p.y() <= image.rows - 1 - half;
}

struct CurveMatch {
  bool found = false;
  Eigen::Vector2d pixel;
  double correlation = -1.0;
};

// Best match of `reference` along the epipolar curve of `from_pixel` (seen by `from`) in `to`,
// sampled uniformly in disparity b f / r between the range limits, refined by a parabola.
CurveMatch SearchCurve(const cv::Mat& reference, const cv::Mat& to, const CahvorModel& from,
                       const CahvorModel& to_camera, const Eigen::Vector2d& from_pixel,
                       const SparseStereoOptions& o) {
  const Eigen::Vector3d ray = from.Unproject(from_pixel);
  const double bf = (to_camera.c - from.c).norm() * from.FocalLengths().x();
  std::vector<Eigen::Vector2d> pixels;
  std::vector<double> scores;
  for (double d = bf / o.max_range_m; d <= bf / o.min_range_m; d += o.disparity_step_px) {
    const auto q = to_camera.Project(Eigen::Vector3d(from.c + (bf / d) * ray));
    if (!q || !Inside(to, *q, o.half_window)) continue;
    pixels.push_back(*q);
    scores.push_back(Ncc(reference, Window(to, *q, o.half_window)));
  }
  CurveMatch out;
  if (scores.size() < 3) return out;
  const size_t best =
      static_cast<size_t>(std::max_element(scores.begin() + 1, scores.end() - 1) - scores.begin());
  const double s0 = scores[best - 1], s1 = scores[best], s2 = scores[best + 1];
  const double curvature = s0 - 2.0 * s1 + s2;
  const double offset = curvature < 0.0 ? std::clamp(0.5 * (s0 - s2) / curvature, -0.5, 0.5) : 0.0;
  const Eigen::Vector2d neighbour = offset >= 0.0 ? pixels[best + 1] : pixels[best - 1];
  out.found = true;
  out.pixel = pixels[best] + std::abs(offset) * (neighbour - pixels[best]);
  out.correlation = s1;
  return out;
}

}  // namespace

void SparseStereoOptions::Check() const {
  RequireOption(half_window >= 1 && half_window <= 50, "SparseStereoOptions.half_window", "1..50");
  RequireOption(min_range_m > 0.0 && max_range_m > min_range_m, "SparseStereoOptions.min_range_m",
                "0 < min_range_m < max_range_m");
  RequireOption(disparity_step_px > 0.0 && disparity_step_px <= 2.0,
                "SparseStereoOptions.disparity_step_px", "in (0, 2] px");
  RequireOption(min_correlation >= -1.0 && min_correlation <= 1.0,
                "SparseStereoOptions.min_correlation", "in [-1, 1]");
  RequireOption(max_vertical_disparity_px >= 0.0, "SparseStereoOptions.max_vertical_disparity_px",
                ">= 0 px");
  RequireOption(max_back_match_px > 0.0, "SparseStereoOptions.max_back_match_px", "> 0 px");
}

SparseStereoMatch MatchPixel(const cv::Mat& left, const cv::Mat& right,
                             const CahvorModel& left_camera, const CahvorModel& right_camera,
                             const Eigen::Vector2d& left_pixel, const SparseStereoOptions& o) {
  o.Check();
  for (const cv::Mat* image : {&left, &right}) {
    if (image->channels() != 1 || (image->depth() != CV_8U && image->depth() != CV_32F)) {
      throw Error("MatchPixel: images must be single-channel CV_8U or CV_32F");
    }
  }
  SparseStereoMatch out;
  const auto reject = [&](const char* filter) {
    out.rejected_by = filter;
    return out;
  };
  if (!Inside(left, left_pixel, o.half_window)) return reject("window outside the image");
  const cv::Mat reference = Window(left, left_pixel, o.half_window);
  cv::Scalar mean, stddev;
  cv::meanStdDev(reference, mean, stddev);
  if (stddev[0] < o.min_texture) return reject("texture");
  const CurveMatch forward =
      SearchCurve(reference, right, left_camera, right_camera, left_pixel, o);
  if (!forward.found) return reject("epipolar curve outside the right image");
  out.right_pixel = forward.pixel;
  out.correlation = forward.correlation;
  out.vertical_disparity_px = forward.pixel.y() - left_pixel.y();
  if (forward.correlation < o.min_correlation) return reject("correlation");
  if (std::abs(out.vertical_disparity_px) >= o.max_vertical_disparity_px) {
    return reject("vertical disparity");
  }
  const CurveMatch back = SearchCurve(Window(right, forward.pixel, o.half_window), left,
                                      right_camera, left_camera, forward.pixel, o);
  if (!back.found || (back.pixel - left_pixel).norm() > o.max_back_match_px) {
    return reject("left-right-left consistency");
  }
  const auto hit = TriangulateRays(left_camera.c, left_camera.Unproject(left_pixel), right_camera.c,
                                   right_camera.Unproject(forward.pixel));
  if (!hit) return reject("intersection not computable");
  out.point = hit->point;
  out.range_m = hit->range_first_m;
  out.ok = true;
  return out;
}

std::vector<SparseTiePoint> MatchInterestPoints(const cv::Mat& left, const cv::Mat& right,
                                                const CahvorModel& left_camera,
                                                const CahvorModel& right_camera,
                                                const std::vector<InterestPoint>& points,
                                                const SparseStereoOptions& options) {
  options.Check();
  std::vector<SparseTiePoint> out(points.size());
  tbb::parallel_for(size_t{0}, points.size(), [&](size_t i) {
    out[i].left = points[i];
    out[i].match = MatchPixel(left, right, left_camera, right_camera, points[i].pixel, options);
  });
  return out;
}

}  // namespace areomap
