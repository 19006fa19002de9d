// Sun geometry and cast shadows shared by the orbital and rover renderers.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace areomap::internal {

// Unit vector toward the sun in ENU; azimuth clockwise from north, elevation above the horizon.
Eigen::Vector3d SunDirection(double azimuth_deg, double elevation_deg);

// Cast shadows on a north-up CV_64F height grid (row 0 = north, square cells of `cell_m`):
// CV_8U, 1 where the terrain toward the sun rises above the sun's ray.
cv::Mat ShadowMask(const cv::Mat& heights, double cell_m, const Eigen::Vector3d& sun);

}  // namespace areomap::internal
