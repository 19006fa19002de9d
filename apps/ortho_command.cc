// areomap ortho IMAGE... --dtm DTM.tif --origin LAT,LON,H [--site-position N,E,D] --out DIR:
// drapes one site's rover images on a DTM (areomap dtm) into an orthophoto (ortho.tif: image,
// valid mask, resolution map, source id) on the DTM's grid.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/cahvor.h"
#include "areomap/map/crs.h"
#include "areomap/map/dtm.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/pds_label.h"
#include "areomap/map/raster.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct OrthoCommandOptions {
  std::vector<std::string> images;
  std::string dtm, out;
  std::vector<double> origin;                        // lat [deg], lon [deg], h [m]
  std::vector<double> site_position{0.0, 0.0, 0.0};  // In the mission (site 0) frame [m].
  double heading_correction_deg = 0.0;  // True minus the labels' (telemetry) heading [deg].
  OrthoOptions ortho;
};

// The label of an image: `<stem>.json` beside it (generator products) or its own PDS label.
ProductGeometry ImageGeometry(const std::filesystem::path& image) {
  std::filesystem::path json = image;
  json.replace_extension(".json");
  if (std::filesystem::exists(json)) {
    std::ifstream in(json);
    const nlohmann::json label = nlohmann::json::parse(in, nullptr, false);
    if (label.is_discarded()) throw Error(json.string() + ": not valid JSON");
    return ParseProductGeometry(label, json.string());
  }
  return ParseProductGeometry(ReadProductLabel(image), image.string());
}

// The image's camera in its site frame (ROVER_FRAME models moved by the label's rover pose).
CahvorModel CameraInSite(const std::filesystem::path& image) {
  const ProductGeometry geometry = ImageGeometry(image);
  if (!geometry.camera) throw Error(image.string() + ": the label has no camera model");
  const CahvorModel camera = CahvorFromLabel(*geometry.camera, image.string());
  if (geometry.camera->reference_frame == "SITE_FRAME") return camera;
  for (const CoordinateFrameLabel& frame : geometry.frames) {
    if (frame.name == geometry.camera->reference_frame && frame.reference_frame == "SITE_FRAME") {
      return camera.Transformed(frame.reference_from_frame);
    }
  }
  throw Error(image.string() + ": no pose from " + geometry.camera->reference_frame +
              " to SITE_FRAME in the label");
}

cv::Mat ReadAnyImage(const std::filesystem::path& path) {
  const std::string extension = path.extension().string();
  if (extension == ".png" || extension == ".PNG" || extension == ".tif" || extension == ".TIF") {
    return ReadImage(path);
  }
  const RasterDataset dataset = RasterDataset::Open(path);
  return dataset.ReadWindow(1, dataset.FullWindow());
}

}  // namespace

// What `areomap ortho --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kOrthoDetails =
    "Drapes one site's rover images on a DTM: per cell within `--max-range` of the cameras\n"
    "(wherever the rover stands in its site frame, e.g. a MER frame tens of metres from its site\n"
    "origin) the visible image (depth test) with the finest ground sample, bilinear; `ortho.tif`\n"
    "with the image, a validity mask, the resolution map [m] and the source-image id; a warning\n"
    "says why when nothing was painted.";

namespace {

void AddOrthoOptions(CLI::App* cmd, OrthoCommandOptions& o) {
  cmd->add_option("images", o.images,
                  "Rover images of one site (PNG with a .json label beside it, or MER .IMG)")
      ->required();
  cmd->add_option("--dtm", o.dtm, "DTM GeoTIFF (areomap dtm) covering the site")->required();
  CheckLatLonHeight(
      cmd->add_option("--origin", o.origin,
                      "Mission origin (site 0's frame): planetocentric lat, east lon [deg], h [m]")
          ->required()
          ->expected(3)
          ->delimiter(','));
  cmd->add_option("--site-position", o.site_position,
                  "The site's origin in site 0's frame: north, east, down [m]")
      ->expected(3)
      ->delimiter(',')
      ->check(FiniteNumber())
      ->capture_default_str();
  cmd->add_option("--heading-correction", o.heading_correction_deg,
                  "True heading minus the labels' (telemetry) heading, e.g. from a bundle "
                  "adjustment [deg, clockwise]")
      ->check(FiniteNumber())
      ->capture_default_str();
  cmd->add_option("--out", o.out, "Output folder (created if needed)")->required();
  cmd->add_option("--max-range", o.ortho.max_range_m, "Paint cells up to this range [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--max-incidence", o.ortho.max_incidence_deg,
                  "Most oblique view accepted (ray vs surface normal) [deg]")
      ->check(NumberIn(0.0, 90.0, Bound::kOpen, Bound::kOpen))
      ->capture_default_str();
}

// The site in the mission: --origin, --site-position and --heading-correction.
SiteGeoreference OrthoSite(const OrthoCommandOptions& o, const Body& body) {
  // Checked while parsing (CheckLatLonHeight).
  const Geographic origin{RadFromDeg(o.origin[0]), RadFromDeg(o.origin[1]), o.origin[2]};
  return SiteGeoreference::InMission(
      body, origin,
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(RadFromDeg(o.heading_correction_deg),
                                                   Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(o.site_position[0], o.site_position[1], o.site_position[2])));
}

std::vector<OrthoSourceImage> ReadOrthoSources(const std::vector<std::string>& images) {
  std::vector<OrthoSourceImage> sources;
  for (size_t i = 0; i < images.size(); ++i) {
    sources.push_back({static_cast<int>(i), ReadAnyImage(images[i]), CameraInSite(images[i])});
  }
  return sources;
}

// Cells of the DTM window under the orthophoto that have an elevation.
int KnownCellsUnderOrtho(const Orthophoto& ortho, const Dtm& dtm) {
  int known_in_window = 0;
  const Eigen::Vector2i offset = ortho.grid.OffsetIn(dtm.layers.grid);
  for (int row = 0; row < ortho.grid.height; ++row) {
    for (int col = 0; col < ortho.grid.width; ++col) {
      known_in_window +=
          std::isfinite(dtm.layers.elevation.at<float>(row + offset.y(), col + offset.x())) ? 1 : 0;
    }
  }
  return known_in_window;
}

nlohmann::json OrthoSummaryJson(const OrthoCommandOptions& o, const Orthophoto& ortho,
                                int known_in_window) {
  return {{"command", "ortho"},
          {"orthophoto", "ortho.tif"},
          {"dtm", o.dtm},
          {"source_ids", o.images},
          {"width", ortho.grid.width},
          {"height", ortho.grid.height},
          {"posting_m", ortho.grid.posting},
          {"valid_cells", ortho.valid_cells},
          {"dtm_cells_in_reach", known_in_window},
          {"coverage_of_dtm",
           known_in_window > 0 ? static_cast<double>(ortho.valid_cells) / known_in_window : 0.0}};
}

// The warning when nothing was painted, and (without --quiet) the one-line summary.
void ReportOrtho(const Orthophoto& ortho, int known_in_window, const std::filesystem::path& path,
                 const GlobalOptions& global) {
  if (ortho.valid_cells == 0) {
    std::cerr << "warning: nothing was painted: "
              << (known_in_window == 0
                      ? "the DTM has no elevation within --max-range of the cameras"
                      : "no valid image pixel sees the DTM within reach (images all nodata, "
                        "or looking away from it?)")
              << "\n";
  }
  if (!global.quiet) {
    std::cout << "wrote " << path.string() << " (" << ortho.valid_cells << " cells painted of "
              << known_in_window << " DTM cells within reach)\n";
  }
}

void RunOrthoCommand(const OrthoCommandOptions& o, const GlobalOptions& global) {
  o.ortho.Check();
  std::vector<std::filesystem::path> inputs(o.images.begin(), o.images.end());
  inputs.push_back(o.dtm);
  OutputFolder out(o.out, OutputPolicy(global, "ortho", {"ortho.tif"}, inputs));
  const ProgressCallback progress = MakeProgressBar(global, "ortho");
  const Body body = Body::Mars2000();
  const SiteGeoreference site = OrthoSite(o, body);
  const std::vector<OrthoSourceImage> sources = ReadOrthoSources(o.images);
  // Only the DTM's cells within reach of the cameras are read (a DTM may be a whole orbital
  // product): its metadata first, then that window.
  const RasterInfo dtm_info = RasterDataset::Open(o.dtm).info();
  if (dtm_info.crs_wkt.empty()) throw Error(o.dtm + ": the DTM has no CRS");
  const MapFrame map = MapFrame::FromCrs(body, Crs::FromWkt(dtm_info.crs_wkt, o.dtm));
  const std::optional<GridSpec> reach =
      OrthophotoWindow(GridOfRaster(dtm_info, o.dtm), site, map, sources, o.ortho);
  if (!reach) {
    throw Error(o.dtm +
                ": the DTM does not reach the cameras (no cell within --max-range of "
                "them)");
  }
  const Dtm dtm = ReadDtm(o.dtm, *reach);
  const Orthophoto ortho = MakeOrthophoto(dtm, site, map, sources, o.ortho, progress);
  WriteOrthophoto(out / "ortho.tif", ortho);
  const int known_in_window = KnownCellsUnderOrtho(ortho, dtm);
  WriteSummary(out.dir(), OrthoSummaryJson(o, ortho, known_in_window));
  out.Commit();
  ReportOrtho(ortho, known_in_window, out.final_dir() / "ortho.tif", global);
}

}  // namespace

void AddOrthoCommand(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<OrthoCommandOptions>();
  auto* cmd = app.add_subcommand(
      "ortho", "Orthophoto of one site's rover images on a DTM (best image per cell, depth test)");
  cmd->footer(kOrthoDetails);
  AddOrthoOptions(cmd, *o);
  cmd->callback([o, &global] { RunOrthoCommand(*o, global); });
}

}  // namespace areomap::cli
