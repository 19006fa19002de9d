// Feeds the input as a crater CSV (x_px, y_px, diameter_px columns; craters.csv, the truth
// catalogues) to ReadCraterCsv(istream), then scores the craters read against themselves.
// Expected: areomap::Error.
#include <limits>
#include <sstream>

#include "areomap/crater/crater_score.h"
#include "areomap/map/error.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in{std::string(areomap::fuzz::AsText(data, size))};
  try {
    const std::vector<areomap::CraterCircle> craters = areomap::ReadCraterCsv(in, "craters.csv");
    if (craters.size() <= 256) {  // Scoring is quadratic; the reader is what is fuzzed.
      (void)areomap::ScoreCraters(craters, craters,
                                  {0.0, 10.0, std::numeric_limits<double>::infinity()});
    }
  } catch (const areomap::Error&) {
  }
  return 0;
}
