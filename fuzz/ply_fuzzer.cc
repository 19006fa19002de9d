// Feeds the input as a binary PLY point cloud to ReadPointCloudPly(istream) (the reader behind
// ReadPointCloudPly(path): header, areomap_* comments, vertex records, point checks).
// Expected: areomap::Error.
#include <sstream>

#include "areomap/map/error.h"
#include "areomap/map/point_cloud_io.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in{std::string(areomap::fuzz::AsText(data, size)), std::ios::binary};
  try {
    (void)areomap::ReadPointCloudPly(in, "fuzz.ply");
  } catch (const areomap::Error&) {
  }
  return 0;
}
