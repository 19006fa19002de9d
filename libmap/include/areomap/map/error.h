// Project-wide error type for bad input (files, options, labels).
//
// Three tiers (STYLE.md #9): programming bugs are assertions; bad files or options throw
// areomap::Error with a message naming the file, the field and what was expected; expected
// per-item failures are std::optional, a flag or NaN.
#pragma once

#include <stdexcept>
#include <string>
#include <string_view>

namespace areomap {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The one form of an option check: throws Error("<field> is invalid: expected <rule>") unless
// `ok`. `field` names the struct and member, e.g. "TraverseOptions.min_leg_m".
void RequireOption(bool ok, std::string_view field, std::string_view rule);

}  // namespace areomap
