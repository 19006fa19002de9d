// Keywords from PDS3 / VICAR product labels, as GDAL exposes them (metadata domain "json:PDS"
// or "json:VICAR"): the camera model and the coordinate frames of MER products.
//
// Frames: a coordinate-system group gives the transform from its frame to its reference frame:
// ORIGIN_ROTATION_QUATERNION (s, x, y, z, scalar first) rotates vectors of the frame into the
// reference frame, ORIGIN_OFFSET_VECTOR is the frame origin in the reference frame [m]. So a
// ROVER_COORDINATE_SYSTEM group referenced to SITE_FRAME is `site_from_rover`.
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/rigid3d.h"

namespace areomap {

// The label of a PDS3 or VICAR product. Throws areomap::Error if the file cannot be opened or
// carries no such label.
nlohmann::json ReadProductLabel(const std::filesystem::path& path);

struct CameraModelLabel {
  std::string model_type;       // "CAHV", "CAHVOR", "CAHVORE", ...
  std::string reference_frame;  // e.g. "ROVER_FRAME".
  // Component id ("C", "A", "H", "V", "O", "R", "E", "T", "P") -> values as in the label.
  std::map<std::string, std::vector<double>> components;
};

struct CoordinateFrameLabel {
  std::string group;            // Label group name, e.g. "ROVER_COORDINATE_SYSTEM".
  std::string name;             // COORDINATE_SYSTEM_NAME, e.g. "ROVER_FRAME".
  std::string reference_frame;  // REFERENCE_COORD_SYSTEM_NAME, e.g. "SITE_FRAME".
  std::vector<int> index;       // COORDINATE_SYSTEM_INDEX (site, drive, ...), may be empty.
  std::array<double, 4> label_quaternion_wxyz{};  // As written in the label (not normalized).
  Rigid3d reference_from_frame;                   // Normalized rotation + offset.
};

struct ProductGeometry {
  std::string instrument_id;
  std::optional<CameraModelLabel> camera;  // From GEOMETRIC_CAMERA_MODEL, if present.
  std::vector<CoordinateFrameLabel> frames;
};

// Extracts the camera model and frames. `source` names the file for errors. A present but
// malformed group (missing MODEL_TYPE, a quaternion of 3 numbers, ...) throws areomap::Error
// naming the group and the keyword.
ProductGeometry ParseProductGeometry(const nlohmann::json& label, std::string_view source);

}  // namespace areomap
