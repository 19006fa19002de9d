#include "areomap/map/pds_label.h"

#include <limits>

#include "areomap/map/error.h"
#include "areomap/map/raster.h"

namespace areomap {
namespace {

const nlohmann::json& RequireKey(const nlohmann::json& group, const std::string& key,
                                 std::string_view source, const std::string& group_name) {
  const auto it = group.find(key);
  if (it == group.end()) {
    throw Error(std::string(source) + ": label group " + group_name + " has no keyword " + key);
  }
  return *it;
}

std::vector<double> NumberList(const nlohmann::json& value, std::string_view source,
                               const std::string& where, size_t expected_size) {
  if (!value.is_array() || (expected_size != 0 && value.size() != expected_size)) {
    throw Error(std::string(source) + ": label keyword " + where + " is invalid: expected " +
                (expected_size ? std::to_string(expected_size) + " numbers" : "a list of numbers"));
  }
  std::vector<double> out;
  for (const auto& item : value) {
    if (!item.is_number()) {
      throw Error(std::string(source) + ": label keyword " + where + " holds '" + item.dump() +
                  "': expected numbers");
    }
    out.push_back(item.get<double>());
  }
  return out;
}

// An index of COORDINATE_SYSTEM_INDEX as an int; throws naming the keyword when it does not fit
// (get<int> would wrap 4294967297 to site 1).
int FrameIndex(const nlohmann::json& value, std::string_view source, const std::string& group) {
  const bool fits = value.is_number_unsigned()
                        ? value.get<unsigned long long>() <=
                              static_cast<unsigned long long>(std::numeric_limits<int>::max())
                        : value.get<long long>() >= std::numeric_limits<int>::min() &&
                              value.get<long long>() <= std::numeric_limits<int>::max();
  if (!fits) {
    throw Error(std::string(source) + ": label keyword " + group +
                ".COORDINATE_SYSTEM_INDEX holds " + value.dump() +
                ": expected indices in int range");
  }
  return value.get<int>();
}

std::string StringOr(const nlohmann::json& group, const std::string& key, std::string fallback) {
  const auto it = group.find(key);
  return (it != group.end() && it->is_string()) ? it->get<std::string>() : fallback;
}

}  // namespace

nlohmann::json ReadProductLabel(const std::filesystem::path& path) {
  const RasterDataset dataset = RasterDataset::Open(path);
  for (const char* domain : {"json:PDS", "json:VICAR", "json:PDS4", "json:ISIS3"}) {
    if (auto label = dataset.LabelJson(domain)) return *label;
  }
  throw Error(path.string() + ": has no PDS3/VICAR/ISIS3 label: expected a planetary product");
}

ProductGeometry ParseProductGeometry(const nlohmann::json& label, std::string_view source) {
  ProductGeometry out;
  if (!label.is_object()) {
    throw Error(std::string(source) + ": label is not a keyword group");
  }
  out.instrument_id = StringOr(label, "INSTRUMENT_ID", "");
  if (const auto it = label.find("GEOMETRIC_CAMERA_MODEL"); it != label.end()) {
    const std::string group = "GEOMETRIC_CAMERA_MODEL";
    CameraModelLabel camera;
    const auto& type = RequireKey(*it, "MODEL_TYPE", source, group);
    if (!type.is_string()) {
      throw Error(std::string(source) + ": " + group + ".MODEL_TYPE is not a string");
    }
    camera.model_type = type.get<std::string>();
    camera.reference_frame = StringOr(*it, "REFERENCE_COORD_SYSTEM_NAME", "");
    const auto& ids = RequireKey(*it, "MODEL_COMPONENT_ID", source, group);
    if (!ids.is_array()) {
      throw Error(std::string(source) + ": " + group +
                  ".MODEL_COMPONENT_ID is invalid: expected a list of names");
    }
    for (size_t i = 0; i < ids.size(); ++i) {
      const std::string key = "MODEL_COMPONENT_" + std::to_string(i + 1);
      const auto& value = RequireKey(*it, key, source, group);
      const std::string id = ids[i].is_string() ? ids[i].get<std::string>() : key;
      camera.components[id] = value.is_array()
                                  ? NumberList(value, source, group + "." + key, 0)
                                  : std::vector<double>{NumberList(nlohmann::json::array({value}),
                                                                   source, group + "." + key, 1)};
    }
    out.camera = std::move(camera);
  }
  for (const auto& [group, value] : label.items()) {
    if (!value.is_object() || group.size() < 18 ||
        group.compare(group.size() - 18, 18, "_COORDINATE_SYSTEM") != 0) {
      continue;
    }
    CoordinateFrameLabel frame;
    frame.group = group;
    frame.name = StringOr(value, "COORDINATE_SYSTEM_NAME", group);
    frame.reference_frame = StringOr(value, "REFERENCE_COORD_SYSTEM_NAME", "");
    if (const auto idx = value.find("COORDINATE_SYSTEM_INDEX"); idx != value.end()) {
      if (idx->is_array()) {
        for (const auto& i : *idx) {
          if (i.is_number_integer()) frame.index.push_back(FrameIndex(i, source, group));
        }
      } else if (idx->is_number_integer()) {
        frame.index.push_back(FrameIndex(*idx, source, group));
      }
    }
    const auto offset = NumberList(RequireKey(value, "ORIGIN_OFFSET_VECTOR", source, group), source,
                                   group + ".ORIGIN_OFFSET_VECTOR", 3);
    const auto q = NumberList(RequireKey(value, "ORIGIN_ROTATION_QUATERNION", source, group),
                              source, group + ".ORIGIN_ROTATION_QUATERNION", 4);
    const Eigen::Quaterniond rotation(q[0], q[1], q[2], q[3]);  // Scalar first in PDS labels.
    if (!(rotation.norm() > 0.5 && rotation.norm() < 1.5)) {
      throw Error(std::string(source) + ": " + group +
                  ".ORIGIN_ROTATION_QUATERNION is not a unit quaternion");
    }
    frame.label_quaternion_wxyz = {q[0], q[1], q[2], q[3]};
    frame.reference_from_frame =
        Rigid3d(rotation, Eigen::Vector3d(offset[0], offset[1], offset[2]));
    out.frames.push_back(std::move(frame));
  }
  return out;
}

}  // namespace areomap
