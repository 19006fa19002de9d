#include "areomap/map/rectification.h"

#include <cmath>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/camera_linearize.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

// Fills the maps from rectified pixel to input pixel of `model` (-1 outside the input).
void BuildMaps(const CahvorModel& rectified, const CameraModel& model,
               const Eigen::Vector2i& input_size, const Eigen::Vector2i& size, cv::Mat* map_x,
               cv::Mat* map_y) {
  *map_x = cv::Mat(size.y(), size.x(), CV_32F);
  *map_y = cv::Mat(size.y(), size.x(), CV_32F);
  const double max_x = input_size.x() - 1.0, max_y = input_size.y() - 1.0;
  tbb::parallel_for(0, size.y(), [&](int y) {
    auto* mx = map_x->ptr<float>(y);
    auto* my = map_y->ptr<float>(y);
    for (int x = 0; x < size.x(); ++x) {
      const Eigen::Vector3d direction = rectified.Unproject(Eigen::Vector2d(x, y));
      const auto pixel = model.Project(Eigen::Vector3d(model.Center() + 1000.0 * direction));
      const bool inside = pixel && pixel->x() >= 0.0 && pixel->x() <= max_x && pixel->y() >= 0.0 &&
                          pixel->y() <= max_y;
      mx[x] = inside ? static_cast<float>(pixel->x()) : -1.0f;
      my[x] = inside ? static_cast<float>(pixel->y()) : -1.0f;
    }
  });
}

}  // namespace

void RectificationOptions::Check() const {
  RequireOption(output_size.minCoeff() >= 0, "RectificationOptions.output_size",
                "zero (the input size) or a positive width and height");
  RequireOption(min_overlap_fraction >= 0.0 && min_overlap_fraction <= 1.0,
                "RectificationOptions.min_overlap_fraction", "0..1");
}

StereoRectification RectifyStereoPair(const CameraModel& left, const CameraModel& right,
                                      const Eigen::Vector2i& input_size,
                                      const RectificationOptions& options) {
  options.Check();
  RequireOption(input_size.minCoeff() > 0, "RectifyStereoPair input_size",
                "a positive width and height");
  StereoRectification out;
  out.size = options.output_size.minCoeff() > 0 ? options.output_size : input_size;
  const Eigen::Vector3d baseline = right.Center() - left.Center();
  out.baseline_m = baseline.norm();
  if (!(out.baseline_m > 1e-6)) {
    throw Error("stereo pair: the two camera centres coincide (baseline " +
                std::to_string(out.baseline_m) + " m): expected a stereo baseline");
  }
  const CahvorModel left_linear = LinearizeToCahv(left, input_size, out.size);
  const CahvorModel right_linear = LinearizeToCahv(right, input_size, out.size);
  const Eigen::Vector3d x_axis = baseline / out.baseline_m;
  const Eigen::Vector3d left_right_axis =
      (left_linear.h - left_linear.PrincipalPoint().x() * left_linear.a).normalized();
  if (x_axis.dot(left_right_axis) <= 0.0) {
    throw Error(
        "stereo pair: the right camera is not to the right of the left one (baseline "
        "points to the left image's left): are the images swapped?");
  }
  Eigen::Vector3d axis = (left_linear.a + right_linear.a).normalized();
  axis = (axis - axis.dot(x_axis) * x_axis).normalized();
  const Eigen::Vector3d down = axis.cross(x_axis).normalized();
  const double hs = 0.5 * (left_linear.FocalLengths().x() + right_linear.FocalLengths().x());
  const double vs = 0.5 * (left_linear.FocalLengths().y() + right_linear.FocalLengths().y());
  const double hc = (out.size.x() - 1.0) / 2.0, vc = (out.size.y() - 1.0) / 2.0;
  for (CahvorModel* m : {&out.left, &out.right}) {
    m->a = axis;
    m->h = hs * x_axis + hc * axis;
    m->v = vs * down + vc * axis;
    m->o = axis;
    m->r.setZero();
  }
  out.left.c = left.Center();
  out.right.c = right.Center();
  out.focal_px = hs;
  BuildMaps(out.left, left, input_size, out.size, &out.left_map_x, &out.left_map_y);
  BuildMaps(out.right, right, input_size, out.size, &out.right_map_x, &out.right_map_y);
  const cv::Mat both = (out.left_map_x >= 0.0f) & (out.right_map_x >= 0.0f);
  out.overlap_fraction =
      static_cast<double>(cv::countNonZero(both)) / (static_cast<double>(out.size.prod()));
  if (out.overlap_fraction < options.min_overlap_fraction) {
    throw Error("stereo pair: the two views overlap on " +
                std::to_string(100.0 * out.overlap_fraction) +
                "% of the rectified image at infinity: expected at least " +
                std::to_string(100.0 * options.min_overlap_fraction) +
                "% (do the cameras look the same way?)");
  }
  return out;
}

cv::Mat RemapToRectified(const cv::Mat& image, const cv::Mat& map_x, const cv::Mat& map_y) {
  cv::Mat out;
  cv::remap(image, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

}  // namespace areomap
