// areomap camera show|linearize|project FILE: rover camera models (CAHV, CAHVOR, CAHVORE from
// PDS/VICAR or generator labels; pinhole from ASP .tsai).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>
#include <variant>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "areomap/map/camera_footprint.h"
#include "areomap/map/camera_linearize.h"
#include "areomap/map/camera_models.h"
#include "areomap/map/coordinate_system.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
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

// One `camera project` stdin line: x y z [m], finite. Prints the error naming the line and what
// was expected, and returns nothing, when the line is not that.
std::optional<Eigen::Vector3d> ReadProjectPoint(const std::string& line, int number) {
  try {
    const Eigen::Vector3d p = ParsePointLine(line, 3);
    if (p.allFinite()) return p;
    std::fprintf(stderr, "error: stdin line %d: expected finite numbers (x y z in metres)\n",
                 number);
  } catch (const Error& e) {
    std::fprintf(stderr, "error: stdin line %d: %s (x y z in metres)\n", number, e.what());
  }
  return std::nullopt;
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

struct FootprintOptions {
  std::vector<std::string> files;
  std::string out;
  double max_range_m = 30.0;
  double ground_z_rover_m = 0.0;
};

// One image of `camera footprint`: its ground footprint and viewing direction in the site frame.
struct FootprintItem {
  std::string name;
  std::vector<Eigen::Vector2d> polygon;
  double azimuth_deg = 0.0, elevation_deg = 0.0;
  Eigen::Vector3d center;
};

struct SiteFootprints {
  std::vector<FootprintItem> items;  // One per file, in order.
  double ground_z = 0.0;             // Site-frame z of the level ground [m].
  int site = -1;
};

// The footprints of `options.files`, which must all carry a rover->site pose, an image size and
// the same site as the first image.
SiteFootprints ReadFootprints(const FootprintOptions& options) {
  SiteFootprints result;
  std::vector<FootprintItem>& items = result.items;
  for (const std::string& file : options.files) {
    const CameraFile camera = ReadCameraForImage(file);
    if (!camera.site_from_frame) {
      throw Error(file + ": no " + camera.frame +
                  " -> SITE_FRAME pose in the label: expected a "
                  "ROVER_COORDINATE_SYSTEM group referenced to SITE_FRAME");
    }
    if (!camera.image_size) throw Error(file + ": the label gives no image size (IMAGE group)");
    if (items.empty()) {
      result.site = camera.site;
      result.ground_z =
          (*camera.site_from_frame * Eigen::Vector3d(0, 0, options.ground_z_rover_m)).z();
    } else if (camera.site != result.site) {
      throw Error(file + ": site " + std::to_string(camera.site) +
                  " differs from the first "
                  "image's site " +
                  std::to_string(result.site) + ": expected one site frame");
    }
    const CameraModel in_site = camera.model.Transformed(*camera.site_from_frame);
    const CahvorModel linear = LinearizeToCahv(in_site, *camera.image_size, *camera.image_size);
    FootprintItem item;
    item.name = std::filesystem::path(file).filename().string();
    item.polygon =
        GroundFootprint(in_site, *camera.image_size, result.ground_z, options.max_range_m);
    item.azimuth_deg = std::atan2(linear.a.y(), linear.a.x()) * 180.0 / M_PI;
    if (item.azimuth_deg < 0.0) item.azimuth_deg += 360.0;
    item.elevation_deg = -std::asin(linear.a.z()) * 180.0 / M_PI;
    item.center = in_site.Center();
    items.push_back(std::move(item));
  }
  return result;
}

// The plot's pixels: 900 px for twice the range around the first camera, north up, east right.
struct PlanView {
  static constexpr int kSize = 900;
  Eigen::Vector2d origin;  // (north, east) at the plot's centre [m]
  double scale = 0.0;      // px per metre

  cv::Point ToPixel(const Eigen::Vector2d& p) const {
    const Eigen::Vector2d d = p - origin;  // (north, east)
    return cv::Point(static_cast<int>(std::lround(kSize / 2.0 + d.y() * scale)),
                     static_cast<int>(std::lround(kSize / 2.0 - d.x() * scale)));
  }
};

struct FootprintPlot {
  cv::Mat image;
  std::vector<cv::Mat> masks;  // Each footprint filled, on the plot's pixels.
};

void DrawPlanViewGrid(cv::Mat& plot, const PlanView& view, double max_range_m) {
  for (int m = -static_cast<int>(max_range_m); m <= max_range_m; m += 5) {
    const cv::Scalar grey(225, 225, 225);
    cv::line(plot, view.ToPixel(view.origin + Eigen::Vector2d(m, -max_range_m)),
             view.ToPixel(view.origin + Eigen::Vector2d(m, max_range_m)), grey);
    cv::line(plot, view.ToPixel(view.origin + Eigen::Vector2d(-max_range_m, m)),
             view.ToPixel(view.origin + Eigen::Vector2d(max_range_m, m)), grey);
  }
}

FootprintPlot DrawFootprints(const SiteFootprints& footprints, const PlanView& view,
                             double max_range_m) {
  constexpr int kSize = PlanView::kSize;
  const std::vector<FootprintItem>& items = footprints.items;
  FootprintPlot result;
  cv::Mat plot(kSize, kSize, CV_8UC3, cv::Scalar(255, 255, 255));
  DrawPlanViewGrid(plot, view, max_range_m);
  const std::vector<cv::Scalar> colours = {
      {200, 60, 0}, {0, 140, 230}, {40, 160, 40}, {160, 0, 160}, {0, 0, 200}};  // RGB order.
  for (size_t i = 0; i < items.size(); ++i) {
    std::vector<cv::Point> points;
    for (const Eigen::Vector2d& p : items[i].polygon) points.push_back(view.ToPixel(p));
    cv::Mat mask(kSize, kSize, CV_8U, cv::Scalar(0));
    cv::fillPoly(mask, std::vector<std::vector<cv::Point>>{points}, cv::Scalar(255));
    result.masks.push_back(mask);
    const cv::Scalar& colour = colours[i % colours.size()];
    cv::polylines(plot, std::vector<std::vector<cv::Point>>{points}, true, colour, 2, cv::LINE_AA);
    cv::circle(plot, view.ToPixel(items[i].center.head<2>()), 4, colour, cv::FILLED);
    char text[160];
    std::snprintf(text, sizeof(text), "%s az %.1f el %.1f", items[i].name.c_str(),
                  items[i].azimuth_deg, items[i].elevation_deg);
    cv::putText(plot, text, cv::Point(10, 25 + 22 * static_cast<int>(i)), cv::FONT_HERSHEY_SIMPLEX,
                0.55, colour, 1, cv::LINE_AA);
  }
  cv::putText(
      plot,
      "N up, E right; grid 5 m; ground z = " + std::to_string(footprints.ground_z) + " m (site)",
      cv::Point(10, kSize - 12), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(90, 90, 90), 1,
      cv::LINE_AA);
  result.image = plot;
  return result;
}

nlohmann::json FootprintImagesJson(const std::vector<FootprintItem>& items,
                                   const std::vector<std::string>& files) {
  nlohmann::json images = nlohmann::json::array();
  for (size_t i = 0; i < items.size(); ++i) {
    nlohmann::json polygon = nlohmann::json::array();
    for (const Eigen::Vector2d& p : items[i].polygon) polygon.push_back({p.x(), p.y()});
    images.push_back(
        {{"file", files[i]},
         {"azimuth_deg", items[i].azimuth_deg},
         {"elevation_deg", items[i].elevation_deg},
         {"camera_center_site_m", {items[i].center.x(), items[i].center.y(), items[i].center.z()}},
         {"footprint_area_m2", PolygonArea(items[i].polygon)},
         {"footprint_site_xy_m", polygon}});
  }
  return images;
}

// The overlap of each image's footprint with the next one's, counted on the plot's pixels.
nlohmann::json ConsecutiveOverlapsJson(const std::vector<cv::Mat>& masks, double scale) {
  nlohmann::json overlaps = nlohmann::json::array();
  for (size_t i = 0; i + 1 < masks.size(); ++i) {
    const double area_px = cv::countNonZero(masks[i] & masks[i + 1]);
    overlaps.push_back({{"images", {i, i + 1}}, {"overlap_m2", area_px / (scale * scale)}});
  }
  return overlaps;
}

void PrintFootprints(const nlohmann::json& images, const FootprintOptions& options) {
  for (const nlohmann::json& image : images) {
    std::printf("%s: azimuth %.1f deg, elevation %.1f deg, footprint %.1f m2\n",
                image["file"].get<std::string>().c_str(), image["azimuth_deg"].get<double>(),
                image["elevation_deg"].get<double>(), image["footprint_area_m2"].get<double>());
  }
  std::printf("wrote %s\n", (std::filesystem::path(options.out) / "footprints.png").c_str());
}

// Plan view (north up, east right) of the footprints of images whose labels place them in one
// site frame, on the level plane through the first image's rover-frame z = ground_z_rover_m.
void WriteFootprints(const FootprintOptions& options, const GlobalOptions& global) {
  OutputFolder out(options.out, OutputPolicy(global, "camera footprint", {"footprints.png"},
                                             {options.files.begin(), options.files.end()}));
  const SiteFootprints footprints = ReadFootprints(options);
  const PlanView view{footprints.items.front().center.head<2>(),
                      PlanView::kSize / (2.2 * options.max_range_m)};
  const FootprintPlot plot = DrawFootprints(footprints, view, options.max_range_m);
  const nlohmann::json images = FootprintImagesJson(footprints.items, options.files);
  const nlohmann::json overlaps = ConsecutiveOverlapsJson(plot.masks, view.scale);
  WriteImage(out / "footprints.png", plot.image);
  WriteSummary(out.dir(), {{"command", "camera footprint"},
                           {"site", footprints.site},
                           {"ground_z_site_m", footprints.ground_z},
                           {"max_range_m", options.max_range_m},
                           {"images", images},
                           {"consecutive_overlaps", overlaps}});
  out.Commit();
  if (!global.quiet) PrintFootprints(images, options);
}

// The options every subcommand but `footprint` takes: the file and its --frame.
void AddCameraFileOptions(CLI::App* cmd, CameraOptions& options) {
  cmd->add_option("file", options.file,
                  "Product with a PDS3/VICAR label (MER .IMG), a generator label (.json), an "
                  "ASP .tsai file, or an image with one of those beside it")
      ->required();
  cmd->add_option("--frame", options.frame,
                  "label: the model's own frame (e.g. ROVER_FRAME); site: moved to the site "
                  "frame with the label's rover->site pose")
      ->check(CLI::IsMember({"label", "site"}))
      ->capture_default_str();
}

// camera linearize: prints (and with --write writes) the model linearized to CAHV.
void LinearizeModel(const CameraOptions& options) {
  const CameraFile file = LoadModel(options);
  Eigen::Vector2i input;
  if (!options.input_size.empty()) {
    input = ParseSize(options.input_size, "--input-size");
  } else if (file.image_size) {
    input = *file.image_size;
  } else {
    throw Error(options.file + ": the label gives no image size: pass --input-size WxH");
  }
  const Eigen::Vector2i output = options.size.empty() ? input : ParseSize(options.size, "--size");
  const CahvorModel cahv = LinearizeToCahv(file.model, input, output);
  CameraFile linear = file;
  linear.model = cahv;
  PrintModel(linear, options.file + " linearized to " + std::to_string(output.x()) + "x" +
                         std::to_string(output.y()));
  if (!options.write.empty()) WriteCameraFile(cahv, file.frame, options.write);
}

// camera project: one "x y" line per stdin line ("nan nan" where it fails); exits 1 if any did.
void ProjectStdinPoints(const CameraOptions& options) {
  const CameraFile file = LoadModel(options);
  const CameraModel& m = file.model;
  std::string line;
  int number = 0, failures = 0;
  while (std::getline(std::cin, line)) {
    ++number;
    if (PointLineIsEmpty(line)) continue;
    const std::optional<Eigen::Vector3d> p = ReadProjectPoint(line, number);
    if (!p) {
      std::printf("nan nan\n");
      ++failures;
      continue;
    }
    const auto pixel = m.Project(*p);
    if (!pixel) {
      std::printf("nan nan\n");
      std::fprintf(stderr,
                   "error: stdin line %d: point is behind the camera or outside the model\n",
                   number);
      ++failures;
      continue;
    }
    std::printf("%.6f %.6f\n", pixel->x(), pixel->y());
    // Pixel centres at integers: the image spans [-0.5, size - 0.5).
    if (file.image_size &&
        !(pixel->x() >= -0.5 && pixel->y() >= -0.5 && pixel->x() < file.image_size->x() - 0.5 &&
          pixel->y() < file.image_size->y() - 0.5)) {
      std::fprintf(stderr, "note: stdin line %d: pixel (%.1f, %.1f) is outside the %dx%d image\n",
                   number, pixel->x(), pixel->y(), file.image_size->x(), file.image_size->y());
    }
  }
  if (failures > 0) throw CLI::RuntimeError(1);
}

void AddFootprintOptions(CLI::App* footprint, FootprintOptions& options) {
  footprint->add_option("files", options.files, "Labelled images of one site")->required();
  footprint->add_option("--out", options.out, "Output folder")->required();
  // At most 10 km: beyond the horizon of any rover camera, and the plot draws a grid line every
  // 5 m of it.
  footprint->add_option("--max-range", options.max_range_m, "Footprint cut [m]")
      ->check(NumberIn(0.0, 1e4, Bound::kOpen))
      ->capture_default_str();
  footprint
      ->add_option("--ground-z-rover", options.ground_z_rover_m,
                   "Ground z in the first image's rover frame [m] (0: rover origin on the "
                   "ground, as the generator's labels)")
      ->check(FiniteNumber())
      ->capture_default_str();
}

}  // namespace

// What `areomap camera --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kCameraDetails =
    "The CAHV/CAHVOR/CAHVORE camera model of a MER product from its label (C, A, H, V, O, R, E;\n"
    "principal point, focal lengths, IFOV), in the label's frame or moved to the site frame with\n"
    "the label's rover→site pose; `linearize` gives the CAHV model that resamples the image "
    "without\n"
    "distortion, `footprint` plots the images' ground footprints, `project` maps 3D points on "
    "stdin\n"
    "to pixels. `areomap ortho` takes CAHV/CAHVOR frames only (not the CAHVORE Hazcam).";

void AddCameraCommand(CLI::App& app, const GlobalOptions& global) {
  auto options = std::make_shared<CameraOptions>();
  auto* camera = app.add_subcommand(
      "camera", "Camera models of rover products (CAHV, CAHVOR, CAHVORE, pinhole .tsai)");
  camera->footer(kCameraDetails);
  camera->require_subcommand(1);
  auto* show = camera->add_subcommand("show", "Print the model and its derived geometry");
  AddCameraFileOptions(show, *options);
  show->callback([options] { PrintModel(LoadModel(*options), options->file); });

  auto* linearize = camera->add_subcommand(
      "linearize",
      "Print the CAHV model that resamples the image without distortion (JPL's "
      "minimum-field-of-view linearization)");
  AddCameraFileOptions(linearize, *options);
  linearize->add_option("--size", options->size, "Output image size WxH (default: the input's)");
  linearize->add_option("--input-size", options->input_size,
                        "Input image size WxH when the file does not give it (.tsai)");
  linearize->add_option("--write", options->write, "Also write the CAHV model as a JSON label");
  linearize->callback([options] { LinearizeModel(*options); });

  auto footprint_options = std::make_shared<FootprintOptions>();
  auto* footprint = camera->add_subcommand(
      "footprint", "Plan view of the images' footprints on a level ground in their site frame");
  AddFootprintOptions(footprint, *footprint_options);
  footprint->callback(
      [footprint_options, &global] { WriteFootprints(*footprint_options, global); });

  auto* project = camera->add_subcommand(
      "project", "Project 3D points (x y z [m] per line on stdin, in --frame) to pixels (x y)");
  AddCameraFileOptions(project, *options);
  project->callback([options] { ProjectStdinPoints(*options); });
}

}  // namespace areomap::cli
