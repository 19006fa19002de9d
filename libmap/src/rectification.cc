#include "areomap/map/rectification.h"

#include <cmath>
#include <string>

#include <Eigen/Geometry>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/camera_linearize.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

// Fills the maps from rectified pixel to input pixel of `model` (-1 outside the input). The
// model sees the rectified ray d where it would see model_from_true * d.
void BuildMaps(const CahvorModel& rectified, const CameraModel& model,
               const Eigen::Matrix3d& model_from_true, const Eigen::Vector2i& input_size,
               const Eigen::Vector2i& size, cv::Mat* map_x, cv::Mat* map_y) {
  *map_x = cv::Mat(size.y(), size.x(), CV_32F);
  *map_y = cv::Mat(size.y(), size.x(), CV_32F);
  const double max_x = input_size.x() - 1.0, max_y = input_size.y() - 1.0;
  tbb::parallel_for(0, size.y(), [&](int y) {
    auto* mx = map_x->ptr<float>(y);
    auto* my = map_y->ptr<float>(y);
    for (int x = 0; x < size.x(); ++x) {
      const Eigen::Vector3d direction =
          model_from_true * rectified.Unproject(Eigen::Vector2d(x, y));
      const auto pixel = model.Project(Eigen::Vector3d(model.Center() + 1000.0 * direction));
      const bool inside = pixel && pixel->x() >= 0.0 && pixel->x() <= max_x && pixel->y() >= 0.0 &&
                          pixel->y() <= max_y;
      mx[x] = inside ? static_cast<float>(pixel->x()) : -1.0f;
      my[x] = inside ? static_cast<float>(pixel->y()) : -1.0f;
    }
  });
}

using Vector5d = Eigen::Matrix<double, 5, 1>;

// The rotation by angle |v| about v (the identity for v = 0).
Eigen::Matrix3d RotationOfVector(const Eigen::Vector3d& v) {
  const double angle = v.norm();
  return angle > 0.0 ? Eigen::AngleAxisd(angle, v / angle).toRotationMatrix()
                     : Eigen::Matrix3d::Identity();
}

// The vertical disparities of left-right correspondences as a function of a small correction
// theta: the baseline turned about `down` (forward tilt) and about the axis (vertical tilt); the
// right camera turned about x, down and the axis [rad].
struct RowAlignment {
  // The rectified frame: x along the baseline, `down`, and the common axis a.
  Eigen::Vector3d x_axis, axis, down;
  double vs = 0.0;  // Vertical focal length [px].
  std::vector<Eigen::Vector3d> left_rays, right_rays;

  // (turn of the baseline, turn of the right camera) for theta.
  std::pair<Eigen::Matrix3d, Eigen::Matrix3d> Rotations(const Vector5d& t) const {
    const Eigen::Vector3d b = t[0] * down + t[1] * axis;
    const Eigen::Vector3d w = t[2] * x_axis + t[3] * down + t[4] * axis;
    return {RotationOfVector(b), RotationOfVector(w)};
  }

  // Vertical disparity of every correspondence after the correction theta [px].
  Eigen::VectorXd Residuals(const Vector5d& t) const {
    const auto [turn_baseline, turn_right] = Rotations(t);
    const Eigen::Vector3d x = turn_baseline * x_axis;
    const Eigen::Vector3d a = (axis - axis.dot(x) * x).normalized();
    const Eigen::Vector3d d = a.cross(x).normalized();
    const size_t n = left_rays.size();
    Eigen::VectorXd r(static_cast<Eigen::Index>(n));
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d& l = left_rays[i];
      const Eigen::Vector3d rr = turn_right * right_rays[i];
      r[static_cast<Eigen::Index>(i)] = vs * (rr.dot(d) / rr.dot(a) - l.dot(d) / l.dot(a));
    }
    return r;
  }
};

RowAlignment MakeRowAlignment(
    const StereoRectification& rect,
    const std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>>& left_right_pixels) {
  const size_t n = left_right_pixels.size();
  RowAlignment problem;
  problem.x_axis = (rect.right.c - rect.left.c).normalized();
  problem.axis = rect.left.a;
  problem.down = problem.axis.cross(problem.x_axis).normalized();
  problem.vs = rect.left.FocalLengths().y();
  problem.left_rays.resize(n);
  problem.right_rays.resize(n);
  for (size_t i = 0; i < n; ++i) {
    problem.left_rays[i] = rect.left.Unproject(left_right_pixels[i].first);
    problem.right_rays[i] = rect.right.Unproject(left_right_pixels[i].second);
  }
  return problem;
}

constexpr double kHuberPx = 1.0, kOutlierPx = 5.0, kPriorRad = 0.1, kStep = 1e-6;

// Theta by 10 Gauss-Newton steps with forward-difference Jacobians, Huber weights (outliers
// beyond kOutlierPx dropped after the first step) and a prior of kPriorRad on each angle.
Vector5d SolveRowAlignment(const RowAlignment& problem) {
  const size_t n = problem.left_rays.size();
  Vector5d theta = Vector5d::Zero();
  std::vector<double> weight(n, 1.0);
  for (int iteration = 0; iteration < 10; ++iteration) {
    const Eigen::VectorXd r = problem.Residuals(theta);
    Eigen::Matrix<double, Eigen::Dynamic, 5> jacobian(r.size(), 5);
    for (int k = 0; k < 5; ++k) {
      Vector5d step = theta;
      step[k] += kStep;
      jacobian.col(k) = (problem.Residuals(step) - r) / kStep;
    }
    Eigen::Matrix<double, 5, 5> normal =
        Eigen::Matrix<double, 5, 5>::Identity() / (kPriorRad * kPriorRad);
    Vector5d gradient = -theta / (kPriorRad * kPriorRad);
    for (size_t i = 0; i < n; ++i) {
      const double e = std::abs(r[static_cast<Eigen::Index>(i)]);
      weight[i] = iteration > 0 && e > kOutlierPx ? 0.0 : (e <= kHuberPx ? 1.0 : kHuberPx / e);
      const auto row = jacobian.row(static_cast<Eigen::Index>(i)).transpose();
      normal += weight[i] * row * row.transpose();
      gradient -= weight[i] * row * r[static_cast<Eigen::Index>(i)];
    }
    theta += normal.ldlt().solve(gradient);
  }
  return theta;
}

// The inliers (within kOutlierPx after the correction) and their RMS vertical disparity before
// and after it.
void ScoreRowAlignment(const RowAlignment& problem, const Vector5d& theta, RectificationFit* fit) {
  const size_t n = problem.left_rays.size();
  const Eigen::VectorXd before = problem.Residuals(Vector5d::Zero());
  const Eigen::VectorXd after = problem.Residuals(theta);
  double sum_before = 0.0, sum_after = 0.0;
  for (size_t i = 0; i < n; ++i) {
    const auto k = static_cast<Eigen::Index>(i);
    if (std::abs(after[k]) > kOutlierPx) continue;
    sum_before += before[k] * before[k];
    sum_after += after[k] * after[k];
    ++fit->inliers;
  }
  if (fit->inliers > 0) {
    fit->rms_before_px = std::sqrt(sum_before / static_cast<double>(fit->inliers));
    fit->rms_after_px = std::sqrt(sum_after / static_cast<double>(fit->inliers));
  }
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
  const RectificationCorrection& correction = options.correction;
  const Eigen::Vector3d baseline = correction.baseline_rotation * (right.Center() - left.Center());
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
  Eigen::Vector3d axis = (left_linear.a + correction.right_rotation * right_linear.a).normalized();
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
  out.right.c = left.Center() + baseline;
  out.focal_px = hs;
  BuildMaps(out.left, left, Eigen::Matrix3d::Identity(), input_size, out.size, &out.left_map_x,
            &out.left_map_y);
  BuildMaps(out.right, right, correction.right_rotation.transpose(), input_size, out.size,
            &out.right_map_x, &out.right_map_y);
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

RectificationFit EstimateRectificationCorrection(
    const StereoRectification& rect, const RectificationCorrection& current,
    const std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>>& left_right_pixels) {
  const size_t n = left_right_pixels.size();
  if (n < 20) {
    throw Error("rectification correction: " + std::to_string(n) +
                " correspondences: expected at least 20");
  }
  const RowAlignment problem = MakeRowAlignment(rect, left_right_pixels);
  const Vector5d theta = SolveRowAlignment(problem);
  RectificationFit fit;
  ScoreRowAlignment(problem, theta, &fit);
  const auto [turn_baseline, turn_right] = problem.Rotations(theta);
  fit.correction.baseline_rotation = turn_baseline * current.baseline_rotation;
  fit.correction.right_rotation = turn_right * current.right_rotation;
  constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;
  fit.baseline_tilt_deg = kDegPerRad * Eigen::AngleAxisd(fit.correction.baseline_rotation).angle();
  fit.right_rotation_deg = kDegPerRad * Eigen::AngleAxisd(fit.correction.right_rotation).angle();
  return fit;
}

cv::Mat RemapToRectified(const cv::Mat& image, const cv::Mat& map_x, const cv::Mat& map_y) {
  cv::Mat out;
  cv::remap(image, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

}  // namespace areomap
