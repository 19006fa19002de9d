// Observations that link rover sites to each other and to the orbital frame: the hand-off from
// rock matching (tie points) and orbital registration (control points) to the bundle adjustment.
//
// Frames: site frames are MER SITE_FRAME (x north, y east, z down, metres) of the site named by
// the index. MBF is Mars body-fixed Cartesian (IAU 2000 ellipsoid), metres. Covariances in m^2
// in the frame of the position they belong to.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

namespace areomap {

// The same ground landmark (a rock peak, a model centre) measured by stereo at two sites.
struct TiePoint {
  std::string id;  // Unique within a run, e.g. "s003-s004-r12".
  int site_a = -1;
  int site_b = -1;
  Eigen::Vector3d position_in_a = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_in_a = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position_in_b = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_in_b = Eigen::Matrix3d::Identity();
  std::string source = "rock";  // "rock", "crater", "manual", ...
};

// A ground point of one site whose Mars body-fixed position is known from orbital data.
struct ControlPoint {
  std::string id;
  int site = -1;
  Eigen::Vector3d position_in_site = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_in_site = Eigen::Matrix3d::Identity();
  Eigen::Vector3d position_mbf = Eigen::Vector3d::Zero();
  Eigen::Matrix3d covariance_mbf = Eigen::Matrix3d::Identity();
  std::string source = "orbital";  // e.g. "hirise_ortho.tif ncc".
};

}  // namespace areomap
