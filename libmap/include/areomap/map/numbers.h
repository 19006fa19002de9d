// Numeric constants shared by areomap code (π is std::numbers::pi).
#pragma once

#include <limits>

namespace areomap {

// "No value": a measure that is undefined for this item (STYLE.md #9's third tier).
inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace areomap
