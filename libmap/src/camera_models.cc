#include "areomap/map/camera_models.h"

#include <fstream>
#include <type_traits>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/pds_label.h"

namespace areomap {
namespace {

template <typename... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
// Spelled out for compilers without aggregate deduction (clang < 17, the fuzz preset).
template <typename... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

nlohmann::json JsonVector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// The image size the label states, if it states one. Throws areomap::Error naming `source` and
// the key when a size is stated but not positive.
std::optional<Eigen::Vector2i> ImageSizeOf(const nlohmann::json& label, const std::string& source) {
  const auto image = label.find("IMAGE");
  if (image == label.end() || !image->is_object()) return std::nullopt;
  const auto lines = image->find("LINES");
  const auto samples = image->find("LINE_SAMPLES");
  if (lines == image->end() || samples == image->end() || !lines->is_number_integer() ||
      !samples->is_number_integer()) {
    return std::nullopt;
  }
  for (const auto& [key, value] : {std::pair{"LINES", lines}, std::pair{"LINE_SAMPLES", samples}}) {
    if (value->get<long long>() <= 0 || value->get<long long>() > 1'000'000) {
      throw Error(source + ": IMAGE." + key + " is " + value->dump() +
                  ": expected a positive image size (at most 1000000)");
    }
  }
  return Eigen::Vector2i(samples->get<int>(), lines->get<int>());
}

}  // namespace

std::string CameraModel::TypeName() const {
  return std::visit(Overloaded{[](const CahvorModel& m) -> std::string {
                                 return m.HasDistortion() ? "CAHVOR" : "CAHV";
                               },
                               [](const CahvoreModel&) -> std::string { return "CAHVORE"; },
                               [](const PinholeModel&) -> std::string { return "PINHOLE"; }},
                    model_);
}

std::optional<Eigen::Vector2d> CameraModel::Project(const Eigen::Vector3d& point) const {
  return std::visit([&](const auto& m) { return m.Project(point); }, model_);
}

CameraRay CameraModel::Unproject(const Eigen::Vector2d& pixel) const {
  return std::visit(Overloaded{[&](const CahvorModel& m) {
                                 return CameraRay{m.c, m.Unproject(pixel)};
                               },
                               [&](const auto& m) { return m.Unproject(pixel); }},
                    model_);
}

Eigen::Vector3d CameraModel::Center() const {
  return std::visit(
      Overloaded{[](const PinholeModel& m) { return m.center; }, [](const auto& m) { return m.c; }},
      model_);
}

CameraModel CameraModel::Transformed(const Rigid3d& b_from_a) const {
  return std::visit([&](const auto& m) { return CameraModel(m.Transformed(b_from_a)); }, model_);
}

CameraFile CameraFileFromLabel(const nlohmann::json& label, const std::string& source) {
  const ProductGeometry geometry = ParseProductGeometry(label, source);
  if (!geometry.camera) {
    throw Error(source + ": label has no GEOMETRIC_CAMERA_MODEL group: expected a camera model");
  }
  CameraFile file;
  file.source = source;
  const CameraModelLabel& camera = *geometry.camera;
  if (camera.model_type == "CAHVORE") {
    file.model = CahvoreFromLabel(camera, source);
  } else {
    file.model = CahvorFromLabel(camera, source);
  }
  file.frame = camera.reference_frame;
  for (const CoordinateFrameLabel& f : geometry.frames) {
    if (f.name == file.frame && f.reference_frame == "SITE_FRAME") {
      file.site_from_frame = f.reference_from_frame;
      if (!f.index.empty()) file.site = f.index.front();
    }
  }
  file.image_size = ImageSizeOf(label, source);
  return file;
}

CameraFile ReadCameraFile(const std::filesystem::path& path) {
  const std::string source = path.string();
  const std::string extension = path.extension().string();
  if (extension == ".tsai") {
    CameraFile file;
    file.model = ReadTsai(path);
    file.frame = "TSAI_WORLD";
    file.source = source;
    return file;
  }
  if (extension == ".json") {
    std::ifstream in(path);
    if (!in) throw Error(source + ": cannot open the camera label");
    nlohmann::json label;
    try {
      label = nlohmann::json::parse(in);
    } catch (const nlohmann::json::exception& e) {
      throw Error(source + ": not a JSON label: " + e.what());
    }
    return CameraFileFromLabel(label, source);
  }
  return CameraFileFromLabel(ReadProductLabel(path), source);
}

CameraFile ReadCameraForImage(const std::filesystem::path& image) {
  if (!std::filesystem::exists(image)) throw Error(image.string() + ": no such file");
  const std::string extension = image.extension().string();
  if (extension != ".png" && extension != ".PNG" && extension != ".tif" && extension != ".TIF") {
    return ReadCameraFile(image);  // A planetary product carries its own label.
  }
  std::filesystem::path tried;
  for (const char* sidecar : {".json", ".tsai"}) {
    std::filesystem::path candidate = image;
    candidate.replace_extension(sidecar);
    if (std::filesystem::exists(candidate)) return ReadCameraFile(candidate);
    tried = candidate;
  }
  std::filesystem::path json = image;
  json.replace_extension(".json");
  throw Error(image.string() + ": no camera model: expected a label beside the image (" +
              json.string() + " or " + tried.string() + ")");
}

nlohmann::json CameraModelGroup(const CameraModel& model, const std::string& frame) {
  return std::visit(
      Overloaded{[&](const CahvorModel& m) -> nlohmann::json {
                   nlohmann::json g = {{"MODEL_TYPE", m.HasDistortion() ? "CAHVOR" : "CAHV"},
                                       {"MODEL_COMPONENT_1", JsonVector(m.c)},
                                       {"MODEL_COMPONENT_2", JsonVector(m.a)},
                                       {"MODEL_COMPONENT_3", JsonVector(m.h)},
                                       {"MODEL_COMPONENT_4", JsonVector(m.v)},
                                       {"REFERENCE_COORD_SYSTEM_NAME", frame}};
                   if (m.HasDistortion()) {
                     g["MODEL_COMPONENT_ID"] = {"C", "A", "H", "V", "O", "R"};
                     g["MODEL_COMPONENT_5"] = JsonVector(m.o);
                     g["MODEL_COMPONENT_6"] = JsonVector(m.r);
                   } else {
                     g["MODEL_COMPONENT_ID"] = {"C", "A", "H", "V"};
                   }
                   return g;
                 },
                 [&](const CahvoreModel& m) -> nlohmann::json {
                   return {{"MODEL_TYPE", "CAHVORE"},
                           {"MODEL_COMPONENT_ID", {"C", "A", "H", "V", "O", "R", "E", "T", "P"}},
                           {"MODEL_COMPONENT_1", JsonVector(m.c)},
                           {"MODEL_COMPONENT_2", JsonVector(m.a)},
                           {"MODEL_COMPONENT_3", JsonVector(m.h)},
                           {"MODEL_COMPONENT_4", JsonVector(m.v)},
                           {"MODEL_COMPONENT_5", JsonVector(m.o)},
                           {"MODEL_COMPONENT_6", JsonVector(m.r)},
                           {"MODEL_COMPONENT_7", JsonVector(m.e)},
                           {"MODEL_COMPONENT_8", static_cast<double>(m.type)},
                           {"MODEL_COMPONENT_9", m.parameter},
                           {"REFERENCE_COORD_SYSTEM_NAME", frame}};
                 },
                 [&](const PinholeModel&) -> nlohmann::json {
                   throw Error(
                       "a pinhole camera has no GEOMETRIC_CAMERA_MODEL group: write it as .tsai");
                 }},
      model.variant());
}

void WriteCameraFile(const CameraModel& model, const std::string& frame,
                     const std::filesystem::path& path) {
  if (const auto* pinhole = std::get_if<PinholeModel>(&model.variant())) {
    if (path.extension() != ".tsai") {
      throw Error(path.string() +
                  ": a pinhole camera is written as .tsai: expected that extension");
    }
    WriteTsai(*pinhole, path);
    return;
  }
  const nlohmann::json label = {{"GEOMETRIC_CAMERA_MODEL", CameraModelGroup(model, frame)}};
  WriteFileAtomically(path, label.dump(2) + "\n");
}

}  // namespace areomap
