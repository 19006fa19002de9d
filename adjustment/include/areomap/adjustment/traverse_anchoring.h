// Anchoring an adjusted traverse: site positions in the traverse frame (site 0's frame), in MBF
// XYZ and in planetocentric lat/lon/h, with 1 sigma horizontal error ellipses, and the per-leg
// relative error (RE, eq. 4.9: position error at the adjacent site / leg length) as in
// Tables 4.6 and 5.2.
//
// Frames and units: traverse frame x north, y east, z down [m]; MBF [m]; latitude planetocentric
// and longitude east [rad] of the foot point on the body's ellipsoid, h above it [m] (geodesy.h).
// Ellipse azimuths are clockwise from north [rad]. Truth is optional: without it the true
// errors are NaN.
#pragma once

#include <optional>
#include <vector>

#include <Eigen/Core>

#include "areomap/adjustment/bundle_adjustment.h"
#include "areomap/map/geodesy.h"

namespace areomap {

// 1 sigma ellipse of a horizontal (north, east) covariance [m^2].
struct ErrorEllipse {
  double semi_major_m = 0.0;
  double semi_minor_m = 0.0;
  double azimuth_rad = 0.0;  // Of the major axis, clockwise from north, in [0, pi).
};
ErrorEllipse HorizontalErrorEllipse(const Eigen::Matrix2d& covariance_north_east);

struct AnchoredSite {
  int site = 0;
  Eigen::Vector3d initial_in_traverse = Eigen::Vector3d::Zero();  // Before adjustment.
  Eigen::Vector3d position_in_traverse = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_in_traverse = Eigen::Matrix3d::Zero();
  Eigen::Vector3d position_mbf = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_mbf = Eigen::Matrix3d::Zero();
  Geographic geographic;  // Planetocentric lat, east lon [rad], h [m].
  ErrorEllipse ellipse;
  double sigma_down_m = 0.0;
  bool only_priors = false;
  // Truth (when given): position and the horizontal errors of the initial and adjusted ones.
  Eigen::Vector3d truth_in_traverse = Eigen::Vector3d::Constant(std::nan(""));
  double initial_error_m = std::nan("");
  double adjusted_error_m = std::nan("");
};

// One leg (consecutive sites a -> b). RE values are fractions (0.01 = 1 %).
struct LegError {
  int site_a = 0;
  int site_b = 0;
  double length_m = 0.0;              // Adjusted (or true, when known) horizontal length.
  double predicted_re = 0.0;          // 1 sigma horizontal relative position error / length.
  double initial_re = std::nan("");   // True error of the telemetry leg / length.
  double adjusted_re = std::nan("");  // True error of the adjusted leg / length.
};

struct AnchoredTraverse {
  std::vector<AnchoredSite> sites;
  std::vector<LegError> legs;
  double length_m = 0.0;  // Sum of leg lengths.
  // With truth: horizontal end-point errors and the median adjusted leg RE.
  double initial_end_error_m = std::nan("");
  double adjusted_end_error_m = std::nan("");
  double median_adjusted_re = std::nan("");
};

// Anchors `result` (from AdjustBundle on `input`). `truth` (traverse_from_site positions, one per
// site) is optional. Throws areomap::Error if the sizes disagree.
AnchoredTraverse AnchorTraverse(const BundleInput& input, const BundleResult& result,
                                const std::vector<Eigen::Vector3d>& truth = {});

}  // namespace areomap
