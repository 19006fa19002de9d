// The site-index check shared by BundleInput::Check (bundle_input.cc) and AdjustBundle's
// free_sites (bundle_adjustment.cc). Throws areomap::Error naming the field, "bundle input: ...".
#pragma once

#include <string>

namespace areomap::bundle_internal {

// `site` must index one of `count` sites.
void CheckSite(int site, int count, const std::string& what);

}  // namespace areomap::bundle_internal
