// The one way a library operation reports its progress and honours a request to stop
// (progress.h's ProgressCallback).
#pragma once

#include <string>
#include <string_view>

#include "areomap/map/error.h"
#include "areomap/map/progress.h"

namespace areomap {

// Calls `progress` (if set) with `fraction` and `stage`; throws areomap::Error("cancelled during
// <stage>") when it asks to stop.
inline void ReportProgress(const ProgressCallback& progress, double fraction,
                           std::string_view stage) {
  if (progress && !progress(fraction, stage)) {
    throw Error("cancelled during " + std::string(stage));
  }
}

}  // namespace areomap
