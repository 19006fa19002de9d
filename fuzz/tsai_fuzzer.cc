// Feeds the input as the text of an ASP `.tsai` pinhole camera file to ReadTsai(istream) (the
// reader behind ReadCameraFile for `.tsai`), then projects and unprojects with the model read.
// Expected: areomap::Error for a malformed file. Anything else is a finding.
#include <sstream>

#include "areomap/map/camera_models.h"
#include "areomap/map/error.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::istringstream in{std::string(areomap::fuzz::AsText(data, size))};
  try {
    const areomap::CameraModel model(areomap::ReadTsai(in, "fuzz.tsai"));
    (void)model.Project(Eigen::Vector3d(0.3, -0.2, 5.0));
    (void)model.Unproject(Eigen::Vector2d(10.0, 20.0));
  } catch (const areomap::Error&) {
  }
  return 0;
}
