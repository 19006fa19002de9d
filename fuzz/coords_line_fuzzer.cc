// Feeds each input line to ParsePointLine (what `areomap coords` reads per stdin line and for
// --origin, and `camera project` with 3 numbers) and converts the point as `coords` would:
// planetocentric → MBF → site frame, and back. Expected: areomap::Error (not a number, wrong
// count, a value out of range).
#include <sstream>
#include <string>

#include "areomap/map/coordinate_system.h"
#include "areomap/map/error.h"
#include "fuzz_support.h"

namespace {

struct Systems {
  areomap::CoordinateSystem planetocentric;
  areomap::CoordinateSystem site;
  areomap::CoordinateSystem planetographic;
};

const Systems& GetSystems() {
  static const Systems systems = [] {
    areomap::CoordinateSystemContext context;
    context.origin = areomap::Geographic{-0.03, 3.08, -1900.0};
    return Systems{areomap::CoordinateSystem::Parse("planetocentric", context),
                   areomap::CoordinateSystem::Parse("site", context),
                   areomap::CoordinateSystem::Parse("planetographic,west,360", context)};
  }();
  return systems;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const Systems& s = GetSystems();
  std::istringstream lines{std::string(areomap::fuzz::AsText(data, size))};
  for (std::string line; std::getline(lines, line);) {
    if (areomap::PointLineIsEmpty(line)) continue;
    try {
      (void)areomap::ParsePointLine(line, 3);
    } catch (const areomap::Error&) {
    }
    try {
      const Eigen::Vector3d point = areomap::ParsePointLine(line);
      const Eigen::Vector3d mbf = s.planetocentric.ToMbf(point);
      (void)s.site.FromMbf(mbf);
      (void)s.planetographic.FromMbf(s.site.ToMbf(point));
    } catch (const areomap::Error&) {
    }
  }
  return 0;
}
