// Input checks shared by the bundle adjustment's sources (bundle_input.cc, bundle_adjustment.cc).
// Each throws areomap::Error naming the field, "bundle input: ...".
#pragma once

#include <string>

#include <Eigen/Core>

namespace areomap::bundle_internal {

// `site` must index one of `count` sites.
void CheckSite(int site, int count, const std::string& what);
// Every coefficient of `m` must be finite.
void CheckFinite(const Eigen::MatrixXd& m, const std::string& what);

}  // namespace areomap::bundle_internal
