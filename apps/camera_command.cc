// areomap camera show|project IMG: the CAHV/CAHVOR model of a product label.
#include <cstdio>
#include <iostream>
#include <sstream>

#include "areomap/map/cahvor.h"
#include "areomap/map/error.h"
#include "areomap/map/pds_label.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct CameraOptions {
  std::string file;
  std::string frame = "label";  // "label" (the model's own frame) or "site".
};

// The model of `file`, in its label's frame or moved to the site frame with the label's
// rover->site pose.
CahvorModel LoadModel(const CameraOptions& options, std::string* frame_name) {
  const ProductGeometry geometry =
      ParseProductGeometry(ReadProductLabel(options.file), options.file);
  if (!geometry.camera) {
    throw Error(options.file + ": label has no GEOMETRIC_CAMERA_MODEL group");
  }
  CahvorModel model = CahvorFromLabel(*geometry.camera, options.file);
  *frame_name = geometry.camera->reference_frame;
  if (options.frame == "site") {
    bool moved = false;
    for (const CoordinateFrameLabel& f : geometry.frames) {
      if (f.name == *frame_name && f.reference_frame == "SITE_FRAME") {
        model = model.Transformed(f.reference_from_frame);
        *frame_name = "SITE_FRAME";
        moved = true;
      }
    }
    if (!moved) {
      throw Error(options.file + ": no " + *frame_name +
                  " -> SITE_FRAME coordinate system in the label: expected a "
                  "ROVER_COORDINATE_SYSTEM group referenced to SITE_FRAME");
    }
  }
  return model;
}

void PrintVector(const char* name, const Eigen::Vector3d& v) {
  std::printf("  %s = %.9g %.9g %.9g\n", name, v.x(), v.y(), v.z());
}

}  // namespace

void AddCameraCommand(CLI::App& app, const GlobalOptions& /*global*/) {
  auto options = std::make_shared<CameraOptions>();
  auto* camera = app.add_subcommand("camera", "Camera models of rover products (CAHV, CAHVOR)");
  camera->require_subcommand(1);
  const auto add_common = [&](CLI::App* cmd) {
    cmd->add_option("file", options->file, "Product with a PDS3/VICAR label (e.g. MER .IMG)")
        ->required();
    cmd->add_option("--frame", options->frame,
                    "label: the model's own frame (e.g. ROVER_FRAME); site: moved to the site "
                    "frame with the label's rover->site pose")
        ->check(CLI::IsMember({"label", "site"}))
        ->capture_default_str();
  };
  auto* show = camera->add_subcommand("show", "Print the model and its derived geometry");
  add_common(show);
  show->callback([options] {
    std::string frame;
    const CahvorModel m = LoadModel(*options, &frame);
    std::printf("%s: %s model in %s\n", options->file.c_str(),
                m.HasDistortion() ? "CAHVOR" : "CAHV", frame.c_str());
    PrintVector("C", m.c);
    PrintVector("A", m.a);
    PrintVector("H", m.h);
    PrintVector("V", m.v);
    if (m.HasDistortion()) {
      PrintVector("O", m.o);
      PrintVector("R", m.r);
    }
    const Eigen::Vector2d pp = m.PrincipalPoint(), f = m.FocalLengths();
    std::printf("  principal point (hc, vc) = %.3f %.3f px\n", pp.x(), pp.y());
    std::printf("  focal lengths (hs, vs) = %.3f %.3f px (%.4f %.4f mrad/px)\n", f.x(), f.y(),
                1e3 / f.x(), 1e3 / f.y());
  });
  auto* project = camera->add_subcommand(
      "project", "Project 3D points (x y z [m] per line on stdin, in --frame) to pixels (x y)");
  add_common(project);
  project->callback([options] {
    std::string frame;
    const CahvorModel m = LoadModel(*options, &frame);
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
        std::fprintf(stderr, "error: stdin line %d: point is behind the camera\n", number);
        ++failures;
        continue;
      }
      std::printf("%.6f %.6f\n", pixel->x(), pixel->y());
    }
    if (failures > 0) throw CLI::RuntimeError(1);
  });
}

}  // namespace areomap::cli
