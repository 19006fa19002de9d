// One interface over the rover camera models (STYLE.md #6): CAHV, CAHVOR, CAHVORE and pinhole
// with Brown distortion. Each model keeps its own templated Project<T> for Ceres; this value type
// dispatches the double versions and reads and writes the files they come in.
//
// Frames: a model lives in the frame its file names (`CameraFile::frame`, e.g. ROVER_FRAME);
// Transformed() moves it. Pixels: (column, row), first pixel centre at (0, 0) for all models.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <variant>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "areomap/map/cahvor.h"
#include "areomap/map/camera_pinhole.h"
#include "areomap/map/rigid3d.h"

namespace areomap {

class CameraModel {
 public:
  using Variant = std::variant<CahvorModel, CahvoreModel, PinholeModel>;

  CameraModel() = default;
  CameraModel(const CahvorModel& m) : model_(m) {}  // NOLINT: implicit on purpose.
  CameraModel(const CahvoreModel& m) : model_(m) {}
  CameraModel(const PinholeModel& m) : model_(m) {}

  // "CAHV", "CAHVOR", "CAHVORE" or "PINHOLE".
  std::string TypeName() const;
  // Pixel of a point [m] in the model's frame; std::nullopt behind the camera or off the model.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point) const;
  // The ray a pixel sees (origin: the camera centre, or CAHVORE's entrance pupil point).
  CameraRay Unproject(const Eigen::Vector2d& pixel) const;
  Eigen::Vector3d Center() const;
  CameraModel Transformed(const Rigid3d& b_from_a) const;
  const Variant& variant() const { return model_; }

 private:
  Variant model_;
};

// A camera model and what its file says about it.
struct CameraFile {
  CameraModel model;
  std::string frame;                          // Frame of the model, e.g. "ROVER_FRAME".
  std::optional<Rigid3d> site_from_frame;     // From a <frame> coordinate system in SITE_FRAME.
  int site = -1;                              // SITE_FRAME index when known.
  std::optional<Eigen::Vector2i> image_size;  // (width, height) from the label's IMAGE group.
  std::string source;                         // The file read.
};

// Reads a model by extension: `.tsai` (ASP pinhole), `.json` (a generator label, laid out like
// GDAL's PDS3 JSON), anything else a product with a PDS3/VICAR label (MER .IMG). Throws
// areomap::Error naming the file when it has no GEOMETRIC_CAMERA_MODEL, an unsupported type or
// malformed components.
CameraFile ReadCameraFile(const std::filesystem::path& path);
// Same from an already parsed label (generator JSON or GDAL's PDS JSON).
CameraFile CameraFileFromLabel(const nlohmann::json& label, const std::string& source);

// The camera of an image: its own label when it carries one (MER .IMG), else `<stem>.json` or
// `<stem>.tsai` beside it. Throws areomap::Error naming the image and the files tried.
CameraFile ReadCameraForImage(const std::filesystem::path& image);

// The GEOMETRIC_CAMERA_MODEL group (MER label layout) of a CAHV, CAHVOR or CAHVORE model; throws
// areomap::Error for a pinhole model (it is written as .tsai).
nlohmann::json CameraModelGroup(const CameraModel& model, const std::string& frame);
// Writes a model atomically: `.tsai` for pinhole, otherwise a JSON label with the
// GEOMETRIC_CAMERA_MODEL group that ReadCameraFile reads back.
void WriteCameraFile(const CameraModel& model, const std::string& frame,
                     const std::filesystem::path& path);

}  // namespace areomap
