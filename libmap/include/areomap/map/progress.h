// Progress reporting from libraries (which never print, STYLE.md #16).
#pragma once

#include <functional>
#include <string_view>

namespace areomap {

// Called with the fraction done in [0, 1] and a short stage name. Return false to ask the
// operation to stop early; it then throws areomap::Error("cancelled ...").
using ProgressCallback = std::function<bool(double fraction, std::string_view stage)>;

// `progress` for one part of a longer operation: fraction f of the part is reported as
// begin + f (end - begin). Empty when `progress` is.
inline ProgressCallback SubProgress(const ProgressCallback& progress, double begin, double end) {
  if (!progress) return nullptr;
  return [progress, begin, end](double fraction, std::string_view stage) {
    return progress(begin + fraction * (end - begin), stage);
  };
}

}  // namespace areomap
