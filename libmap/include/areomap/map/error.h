// Project-wide error type for bad input (files, options, labels).
//
// Three tiers (STYLE.md #9): programming bugs are assertions; bad files or options throw
// areomap::Error with a message naming the file, the field and what was expected; expected
// per-item failures are std::optional, a flag or NaN.
#pragma once

#include <stdexcept>
#include <string>

namespace areomap {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace areomap
