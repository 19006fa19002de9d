// Feeds the input as an adjustment network JSON (docs/adjustment-format.md) to ReadBundleInput
// and ReadTiePoints, the readers behind `areomap adjust`. They take paths: the bytes go to a
// scratch file. Expected: areomap::Error.
#include "areomap/adjustment/bundle_io.h"
#include "areomap/map/error.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path path =
      areomap::fuzz::WriteScratchFile("network.json", areomap::fuzz::AsText(data, size));
  try {
    (void)areomap::ReadBundleInput({path});
  } catch (const areomap::Error&) {
  }
  try {
    (void)areomap::ReadTiePoints(path);
  } catch (const areomap::Error&) {
  }
  return 0;
}
