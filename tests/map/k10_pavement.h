// Evaluation of a dense-stereo cloud of the real K10 pair (../shared/data/k10: rocks on
// pavement, ASP .tsai cameras, z down): a robust plane through the pavement 1.5-4 m away (the
// near rock's columns, full-size left x 400-760, and the rover body, rows > 600, excluded), its
// robust RMS (1.4826 x median |residual|) against the error model's RMS along the normal, and
// the near rock's 95th-percentile height above it (full-size left x 450-700, y 340-580), and the
// points of the whole cloud that lie under the plane by more than 1 m + 3 sigma (their own,
// along the normal): nothing the camera sees is inside the pavement.
// Shared by the unit test (half size) and the stereo bench (full size).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "areomap/map/point_cloud.h"

namespace areomap::testing {

// Least-squares plane with 3-sigma trimming: (unit normal n, offset d), n . p = d, n up (-z).
inline std::pair<Eigen::Vector3d, double> FitPlane(const std::vector<Eigen::Vector3d>& points) {
  std::vector<bool> keep(points.size(), true);
  Eigen::Vector3d normal = -Eigen::Vector3d::UnitZ();
  double offset = 0.0;
  for (int iteration = 0; iteration < 5; ++iteration) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    int n = 0;
    for (size_t i = 0; i < points.size(); ++i) {
      if (keep[i]) mean += points[i], ++n;
    }
    mean /= n;
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (size_t i = 0; i < points.size(); ++i) {
      if (keep[i]) scatter += (points[i] - mean) * (points[i] - mean).transpose();
    }
    normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
    if (normal.z() > 0) normal = -normal;
    offset = normal.dot(mean);
    double sum = 0.0;
    for (size_t i = 0; i < points.size(); ++i) {
      if (keep[i]) sum += std::pow(normal.dot(points[i]) - offset, 2);
    }
    const double rms = std::sqrt(sum / n);
    for (size_t i = 0; i < points.size(); ++i) {
      keep[i] = std::abs(normal.dot(points[i]) - offset) < 3.0 * rms;
    }
  }
  return {normal, offset};
}

struct K10Pavement {
  size_t pavement_points = 0, rock_points = 0;
  double robust_rms_m = 0.0;      // Of the pavement about its plane.
  double model_rms_m = 0.0;       // Error model (point covariances) along the plane normal.
  double rock_top_m = 0.0;        // 95th-percentile height of the near rock above the plane.
  size_t underground_points = 0;  // Deeper than 1 m + 3 sigma below the plane.
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
};

// `scale`: full-size pixels per cloud pixel (2 for the half-size images).
inline K10Pavement EvaluateK10Pavement(const PointCloud& cloud, double scale) {
  K10Pavement out;
  const auto is_pavement = [&](const StereoPoint& p) {
    const double r = (p.position - cloud.camera_center).norm();
    const double x = scale * p.left_x, y = scale * p.left_y;
    return r >= 1.5 && r <= 4.0 && !(x > 400 && x < 760) && y <= 600;
  };
  std::vector<Eigen::Vector3d> pavement;
  std::vector<const StereoPoint*> rock;
  for (const StereoPoint& p : cloud.points) {
    const double x = scale * p.left_x, y = scale * p.left_y;
    if (x > 450 && x < 700 && y > 340 && y < 580) rock.push_back(&p);
    if (is_pavement(p)) pavement.push_back(p.position);
  }
  out.pavement_points = pavement.size();
  out.rock_points = rock.size();
  if (pavement.size() < 3) return out;
  const auto [normal, offset] = FitPlane(pavement);
  out.normal = normal;
  std::vector<double> abs_residuals;
  double model_sq = 0.0;
  for (const StereoPoint& p : cloud.points) {
    if (!is_pavement(p)) continue;
    abs_residuals.push_back(std::abs(normal.dot(p.position) - offset));
    model_sq += normal.dot(p.covariance * normal);
  }
  for (const StereoPoint& p : cloud.points) {
    const double height = normal.dot(p.position) - offset;
    if (height < -(1.0 + 3.0 * std::sqrt(normal.dot(p.covariance * normal)))) {
      ++out.underground_points;
    }
  }
  std::sort(abs_residuals.begin(), abs_residuals.end());
  out.robust_rms_m = 1.4826 * abs_residuals[abs_residuals.size() / 2];
  out.model_rms_m = std::sqrt(model_sq / static_cast<double>(abs_residuals.size()));
  if (!rock.empty()) {
    std::vector<double> heights;
    for (const StereoPoint* p : rock) heights.push_back(normal.dot(p->position) - offset);
    std::sort(heights.begin(), heights.end());
    out.rock_top_m = heights[heights.size() * 95 / 100];
  }
  return out;
}

}  // namespace areomap::testing
