// Feeds the input as a mission site-poses CSV (telemetry/sites.csv, truth/sites.csv) to
// ReadSitePosesCsv(istream). Expected: areomap::Error.
#include <sstream>

#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in{std::string(areomap::fuzz::AsText(data, size))};
  try {
    (void)areomap::ReadSitePosesCsv(in, "sites.csv");
  } catch (const areomap::Error&) {
  }
  return 0;
}
