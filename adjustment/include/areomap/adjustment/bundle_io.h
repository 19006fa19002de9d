// Reading and writing bundle-adjustment inputs as JSON (docs/adjustment-format.md).
//
// Control points give their position as "position_mbf_m", as "lat_deg"/"lon_deg"/"h_m"
// (planetocentric, east, above the ellipsoid) or as "position_traverse_m" (site 0's frame), and
// their covariance as "covariance_mbf_m2", "covariance_traverse_m2" or "sigma_horizontal_m" +
// "sigma_vertical_m" (local level at the point).
// One or more files are merged: the first must give "origin" and "sites"; any file may add
// "priors", "tie_points", "control_points", "heights" and "truth". Units: metres, degrees at
// this I/O boundary; positions in site frames (x north, y east, z down) or MBF.
// Failure: a missing file, bad JSON or a missing/ill-typed field throws areomap::Error naming
// the file and the field (e.g. "net.json: tie_points[3].covariance_in_a_m2: expected a 3x3
// array of numbers").
#pragma once

#include <filesystem>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "areomap/adjustment/bundle_adjustment.h"

namespace areomap {

struct BundleInputFile {
  BundleInput input;
  std::vector<Eigen::Vector3d> truth;  // True site positions (traverse frame), when given.
};

BundleInputFile ReadBundleInput(const std::vector<std::filesystem::path>& paths);

// The "tie_points" of one such file alone (e.g. a leg's tie_points.json of `areomap run`), with
// the same field checks and messages; none when the file has no "tie_points".
std::vector<TiePoint> ReadTiePoints(const std::filesystem::path& path);

// The "tie_points" / "control_points" arrays of that format alone, e.g. for a file that only adds
// observations to a network (covariances written in full).
nlohmann::json TiePointsToJson(const std::vector<TiePoint>& tie_points);
nlohmann::json ControlPointsToJson(const std::vector<ControlPoint>& control_points);

// The JSON document ReadBundleInput reads back to the same input (covariances written in full).
nlohmann::json BundleInputToJson(const BundleInput& input,
                                 const std::vector<Eigen::Vector3d>& truth = {});

}  // namespace areomap
