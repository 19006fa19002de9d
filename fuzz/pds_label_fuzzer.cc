// Feeds the input as a planetary product file (PDS3 / VICAR label, then pixels) to
// ReadCameraFile, which opens it with GDAL (ReadProductLabel: the label as JSON) and parses the
// camera model and coordinate frames (ParseProductGeometry, CameraFileFromLabel). GDAL insists
// on a path: the bytes go to a scratch file. Expected: areomap::Error.
#include "areomap/map/camera_models.h"
#include "areomap/map/error.h"
#include "areomap/map/pds_label.h"
#include "fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::filesystem::path path =
      areomap::fuzz::WriteScratchFile("product.IMG", areomap::fuzz::AsText(data, size));
  try {
    const nlohmann::json label = areomap::ReadProductLabel(path);
    (void)areomap::ParseProductGeometry(label, path.string());
    (void)areomap::CameraFileFromLabel(label, path.string());
  } catch (const areomap::Error&) {
  }
  return 0;
}
