// Feeds the input as a JSON camera label (the generator's label, laid out like GDAL's PDS3 JSON
// of a MER product) the way ReadCameraFile reads `.json`: parse, then CameraFileFromLabel
// (ParseProductGeometry + the CAHV/CAHVOR/CAHVORE builders), then projects and unprojects.
// Expected: a JSON parse error (ReadCameraFile reports it as areomap::Error) or areomap::Error.
#include <nlohmann/json.hpp>

#include "areomap/map/camera_models.h"
#include "areomap/map/error.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const nlohmann::json label = nlohmann::json::parse(areomap::fuzz::AsText(data, size), nullptr,
                                                     /*allow_exceptions=*/false);
  if (label.is_discarded()) return 0;
  try {
    const areomap::CameraFile file = areomap::CameraFileFromLabel(label, "fuzz.json");
    (void)file.model.Project(Eigen::Vector3d(0.3, -0.2, 5.0));
    (void)file.model.Unproject(Eigen::Vector2d(10.0, 20.0));
  } catch (const areomap::Error&) {
  }
  return 0;
}
