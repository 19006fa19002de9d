// areomap camera show|linearize|project FILE: rover camera models (CAHV, CAHVOR, CAHVORE from
// PDS/VICAR or generator labels; pinhole from ASP .tsai).
#include <cstdio>
#include <iostream>
#include <sstream>
#include <variant>

#include "areomap/map/camera_linearize.h"
#include "areomap/map/camera_models.h"
#include "areomap/map/error.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct CameraOptions {
  std::string file;
  std::string frame = "label";  // "label" (the model's own frame) or "site".
  std::string size;             // linearize: output "WxH"; empty = the input size.
  std::string input_size;       // linearize: input "WxH" when the file does not say.
  std::string write;            // linearize: write the CAHV model as a JSON label here.
};

// The model of `file` (a product, a label, a .tsai, or an image with a label beside it), in its
// own frame or moved to the site frame with the label's rover->site pose.
CameraFile LoadModel(const CameraOptions& options) {
  CameraFile file = ReadCameraForImage(options.file);
  if (options.frame == "site") {
    if (!file.site_from_frame) {
      throw Error(options.file + ": no " + file.frame +
                  " -> SITE_FRAME coordinate system in the label: expected a "
                  "ROVER_COORDINATE_SYSTEM group referenced to SITE_FRAME");
    }
    file.model = file.model.Transformed(*file.site_from_frame);
    file.frame = "SITE_FRAME";
  }
  return file;
}

Eigen::Vector2i ParseSize(const std::string& text, const char* option) {
  int w = 0, h = 0;
  char x = 0;
  std::istringstream in(text);
  if (!(in >> w >> x >> h) || (x != 'x' && x != 'X') || w <= 0 || h <= 0 || !in.eof()) {
    throw Error(std::string(option) + " '" + text +
                "' is invalid: expected WIDTHxHEIGHT, e.g. 1024x1024");
  }
  return {w, h};
}

void PrintVector(const char* name, const Eigen::Vector3d& v) {
  std::printf("  %s = %.9g %.9g %.9g\n", name, v.x(), v.y(), v.z());
}

void PrintCahv(const Eigen::Vector3d& a, const Eigen::Vector3d& h, const Eigen::Vector3d& v) {
  const Eigen::Vector2d pp(a.dot(h), a.dot(v));
  const Eigen::Vector2d f(a.cross(h).norm(), a.cross(v).norm());
  std::printf("  principal point (hc, vc) = %.3f %.3f px\n", pp.x(), pp.y());
  std::printf("  focal lengths (hs, vs) = %.3f %.3f px (%.4f %.4f mrad/px)\n", f.x(), f.y(),
              1e3 / f.x(), 1e3 / f.y());
}

void PrintModel(const CameraFile& file, const std::string& name) {
  const CameraModel& model = file.model;
  std::printf("%s: %s model in %s\n", name.c_str(), model.TypeName().c_str(), file.frame.c_str());
  if (const auto* m = std::get_if<CahvorModel>(&model.variant())) {
    PrintVector("C", m->c);
    PrintVector("A", m->a);
    PrintVector("H", m->h);
    PrintVector("V", m->v);
    if (m->HasDistortion()) {
      PrintVector("O", m->o);
      PrintVector("R", m->r);
    }
    PrintCahv(m->a, m->h, m->v);
  } else if (const auto* e = std::get_if<CahvoreModel>(&model.variant())) {
    PrintVector("C", e->c);
    PrintVector("A", e->a);
    PrintVector("H", e->h);
    PrintVector("V", e->v);
    PrintVector("O", e->o);
    PrintVector("R", e->r);
    PrintVector("E", e->e);
    std::printf("  T = %d P = %.9g (linearity %.9g)\n", e->type, e->parameter, e->Linearity());
    PrintCahv(e->a, e->h, e->v);
  } else {
    const auto& p = std::get<PinholeModel>(model.variant());
    std::printf("  fu fv = %.9g %.9g  cu cv = %.9g %.9g  pitch = %.9g\n", p.fu, p.fv, p.cu, p.cv,
                p.pitch);
    PrintVector("C", p.center);
    PrintVector("axis", p.world_from_camera * p.w_direction);
    std::printf("  k1 k2 p1 p2 = %.9g %.9g %.9g %.9g\n", p.k1, p.k2, p.p1, p.p2);
  }
}

}  // namespace

void AddCameraCommand(CLI::App& app, const GlobalOptions& /*global*/) {
  auto options = std::make_shared<CameraOptions>();
  auto* camera = app.add_subcommand(
      "camera", "Camera models of rover products (CAHV, CAHVOR, CAHVORE, pinhole .tsai)");
  camera->require_subcommand(1);
  const auto add_common = [&](CLI::App* cmd) {
    cmd->add_option("file", options->file,
                    "Product with a PDS3/VICAR label (MER .IMG), a generator label (.json), an "
                    "ASP .tsai file, or an image with one of those beside it")
        ->required();
    cmd->add_option("--frame", options->frame,
                    "label: the model's own frame (e.g. ROVER_FRAME); site: moved to the site "
                    "frame with the label's rover->site pose")
        ->check(CLI::IsMember({"label", "site"}))
        ->capture_default_str();
  };
  auto* show = camera->add_subcommand("show", "Print the model and its derived geometry");
  add_common(show);
  show->callback([options] { PrintModel(LoadModel(*options), options->file); });

  auto* linearize = camera->add_subcommand(
      "linearize",
      "Print the CAHV model that resamples the image without distortion (JPL's "
      "minimum-field-of-view linearization)");
  add_common(linearize);
  linearize->add_option("--size", options->size, "Output image size WxH (default: the input's)");
  linearize->add_option("--input-size", options->input_size,
                        "Input image size WxH when the file does not give it (.tsai)");
  linearize->add_option("--write", options->write, "Also write the CAHV model as a JSON label");
  linearize->callback([options] {
    const CameraFile file = LoadModel(*options);
    Eigen::Vector2i input;
    if (!options->input_size.empty()) {
      input = ParseSize(options->input_size, "--input-size");
    } else if (file.image_size) {
      input = *file.image_size;
    } else {
      throw Error(options->file + ": the label gives no image size: pass --input-size WxH");
    }
    const Eigen::Vector2i output =
        options->size.empty() ? input : ParseSize(options->size, "--size");
    const CahvorModel cahv = LinearizeToCahv(file.model, input, output);
    CameraFile linear = file;
    linear.model = cahv;
    PrintModel(linear, options->file + " linearized to " + std::to_string(output.x()) + "x" +
                           std::to_string(output.y()));
    if (!options->write.empty()) WriteCameraFile(cahv, file.frame, options->write);
  });

  auto* project = camera->add_subcommand(
      "project", "Project 3D points (x y z [m] per line on stdin, in --frame) to pixels (x y)");
  add_common(project);
  project->callback([options] {
    const CameraModel m = LoadModel(*options).model;
    std::string line;
    int number = 0, failures = 0;
    while (std::getline(std::cin, line)) {
      ++number;
      std::istringstream in(line);
      Eigen::Vector3d p;
      if (!(in >> p.x() >> p.y() >> p.z())) {
        if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
        std::printf("nan nan\n");
        std::fprintf(stderr, "error: stdin line %d: expected 3 numbers (x y z in metres)\n",
                     number);
        ++failures;
        continue;
      }
      const auto pixel = m.Project(p);
      if (!pixel) {
        std::printf("nan nan\n");
        std::fprintf(stderr,
                     "error: stdin line %d: point is behind the camera or outside the model\n",
                     number);
        ++failures;
        continue;
      }
      std::printf("%.6f %.6f\n", pixel->x(), pixel->y());
    }
    if (failures > 0) throw CLI::RuntimeError(1);
  });
}

}  // namespace areomap::cli
