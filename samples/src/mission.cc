#include "areomap/samples/mission.h"

#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <sstream>

#include <tbb/parallel_for.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/raster.h"
#include "areomap/map/report_progress.h"

namespace areomap {
namespace {

// Fixed-precision number formatting so that files are byte-identical across runs.
std::string Fixed(double value, int decimals) {
  if (std::abs(value) < 0.5 * std::pow(10.0, -decimals)) value = 0.0;  // No "-0.000".
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.*f", decimals, value);
  return buffer;
}

struct CsvTable {
  std::string text;
  void Row(const std::vector<std::string>& cells) {
    for (size_t i = 0; i < cells.size(); ++i) text += (i ? "," : "") + cells[i];
    text += "\n";
  }
};

// Rotation of the rover frame (x forward, y right, z down) into a level site frame (x north,
// y east, z down) for a heading clockwise from north: a rotation about z (down).
Eigen::Quaterniond SiteFromRoverRotation(double heading) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()));
}

nlohmann::json Vector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

std::string Lower(std::string text) {
  for (char& c : text) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return text;
}

struct Instrument {
  const StereoCameraOptions* camera;
  std::vector<StereoPointing> pointings;
};

// Writes a contact sheet for people: the given 8-bit tiles, 5 per row.
void WriteContactSheet(const std::vector<cv::Mat>& tiles, const std::filesystem::path& path) {
  const int columns = std::min<int>(5, static_cast<int>(tiles.size()));
  const int rows = (static_cast<int>(tiles.size()) + columns - 1) / columns;
  const int tile_w = tiles.front().cols, tile_h = tiles.front().rows;
  cv::Mat sheet(rows * tile_h, columns * tile_w, CV_8U, cv::Scalar(0));
  for (size_t i = 0; i < tiles.size(); ++i) {
    const int r = static_cast<int>(i) / columns, c = static_cast<int>(i) % columns;
    tiles[i].copyTo(sheet(cv::Rect(c * tile_w, r * tile_h, tile_w, tile_h)));
  }
  WriteImage(path, sheet);
}

// Renders one instrument's stereo panorama at a site (both cameras of every pointing, in
// parallel), writes images, labels and a contact sheet, and returns the manifest entries.
std::vector<nlohmann::json> RenderPanorama(const SiteMesh& mesh, const Instrument& instrument,
                                           const Rigid3d& enu_from_rover,
                                           const Rigid3d& believed_site_from_rover, int site,
                                           const std::filesystem::path& out_dir,
                                           const std::string& folder_name, int bits,
                                           uint32_t seed) {
  const StereoCameraOptions& o = *instrument.camera;
  const std::string prefix = Lower(o.name);
  const size_t count = 2 * instrument.pointings.size();
  std::vector<nlohmann::json> entries(count);
  std::vector<cv::Mat> left_tiles(instrument.pointings.size());  // Quarter size, 8-bit.
  const double max_dn = std::pow(2.0, bits) - 1.0;
  tbb::parallel_for(size_t{0}, count, [&](size_t index) {
    const size_t pair = index / 2;
    const int side = static_cast<int>(index % 2);
    const CahvorModel camera = StereoCameras(o, instrument.pointings[pair])[side];
    const SiteMesh::Image image = mesh.Render(camera.Transformed(enu_from_rover), o.width, o.height,
                                              seed + static_cast<uint32_t>(index));
    char name[96];
    std::snprintf(name, sizeof(name), "%s_p%02zu_%s", prefix.c_str(), pair,
                  side == 0 ? "left" : "right");
    const std::string instrument_id = o.name + (side == 0 ? "_LEFT" : "_RIGHT");
    const std::string relative = folder_name + "/" + name;
    WriteImage(out_dir / (relative + ".png"), image.dn);
    if (side == 0) {
      cv::Mat tile;
      cv::resize(image.dn, tile, cv::Size(o.width / 4, o.height / 4), 0, 0, cv::INTER_AREA);
      tile.convertTo(left_tiles[pair], CV_8U, 255.0 / (0.7 * max_dn));
    }
    WriteFileAtomically(out_dir / (relative + ".json"),
                        RoverImageLabel(instrument_id, site, camera, believed_site_from_rover,
                                        o.width, o.height, bits)
                                .dump(2) +
                            "\n");
    entries[index] = {{"instrument", instrument_id},
                      {"pair", pair},
                      {"image", relative + ".png"},
                      {"label", relative + ".json"}};
  });
  WriteContactSheet(left_tiles, out_dir / folder_name / (prefix + "_left_contact_sheet.png"));
  return entries;
}

}  // namespace

nlohmann::json RoverImageLabel(const std::string& instrument_id, int site,
                               const CahvorModel& camera, const Rigid3d& site_from_rover, int width,
                               int height, int bits) {
  const Eigen::Quaterniond& q = site_from_rover.rotation;
  return {
      {"INSTRUMENT_ID", instrument_id},
      {"IMAGE", {{"LINES", height}, {"LINE_SAMPLES", width}, {"SAMPLE_BITS", bits}}},
      {"GEOMETRIC_CAMERA_MODEL",
       {{"MODEL_TYPE", "CAHVOR"},
        {"MODEL_COMPONENT_ID", {"C", "A", "H", "V", "O", "R"}},
        {"MODEL_COMPONENT_1", Vector(camera.c)},
        {"MODEL_COMPONENT_2", Vector(camera.a)},
        {"MODEL_COMPONENT_3", Vector(camera.h)},
        {"MODEL_COMPONENT_4", Vector(camera.v)},
        {"MODEL_COMPONENT_5", Vector(camera.o)},
        {"MODEL_COMPONENT_6", Vector(camera.r)},
        {"REFERENCE_COORD_SYSTEM_NAME", "ROVER_FRAME"}}},
      {"ROVER_COORDINATE_SYSTEM",
       {{"COORDINATE_SYSTEM_NAME", "ROVER_FRAME"},
        {"COORDINATE_SYSTEM_INDEX", {site}},
        {"ORIGIN_OFFSET_VECTOR", Vector(site_from_rover.translation)},
        {"ORIGIN_ROTATION_QUATERNION", {q.w(), q.x(), q.y(), q.z()}},
        {"REFERENCE_COORD_SYSTEM_NAME", "SITE_FRAME"},
        {"REFERENCE_COORD_SYSTEM_INDEX", site}}},
  };
}

void TraverseOptions::Check() const {
  RequireOption(site_count >= 1 && site_count <= 1000, "TraverseOptions.site_count", "1..1000");
  RequireOption(min_leg_m > 0.0, "TraverseOptions.min_leg_m", "a positive leg length [m]");
  RequireOption(max_leg_m >= min_leg_m, "TraverseOptions.max_leg_m", ">= min_leg_m");
  RequireOption(max_turn_deg >= 0.0 && max_turn_deg <= 180.0, "TraverseOptions.max_turn_deg",
                "0..180 degrees");
}

void TelemetryErrorModel::Check() const {
  RequireOption(scale_sigma >= 0.0 && scale_sigma < 0.5, "TelemetryErrorModel.scale_sigma",
                "0..0.5");
  RequireOption(heading_drift_sigma_deg >= 0.0 && heading_drift_sigma_deg < 45.0,
                "TelemetryErrorModel.heading_drift_sigma_deg", "0..45 degrees");
}

Traverse PlanTraverse(const TraverseOptions& options, const TelemetryErrorModel& errors,
                      double half_extent_m, uint32_t seed) {
  options.Check();
  errors.Check();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gauss(0.0, 1.0);
  Traverse t;
  const double margin = 0.75 * half_extent_m;
  double heading = 2.0 * std::numbers::pi * unit(rng);  // Clockwise from north.
  Eigen::Vector2d truth_en(0.0, 0.0);                   // (east, north)
  Eigen::Vector2d measured_en(0.0, 0.0);
  double heading_error = 0.0;
  t.truth.push_back({0, Eigen::Vector3d::Zero(), heading});
  t.telemetry.push_back({0, Eigen::Vector3d::Zero(), heading});
  for (int site = 1; site < options.site_count; ++site) {
    const double length = options.min_leg_m + (options.max_leg_m - options.min_leg_m) * unit(rng);
    double turn = RadFromDeg(options.max_turn_deg) * (2.0 * unit(rng) - 1.0);
    Eigen::Vector2d step(std::sin(heading + turn), std::cos(heading + turn));
    if ((truth_en + length * step).cwiseAbs().maxCoeff() > margin) {
      // Head back toward the origin when the next site would leave the scene.
      const Eigen::Vector2d home = -truth_en.normalized();
      turn = std::atan2(home.x(), home.y()) - heading;
      step = home;
    }
    heading += turn;
    truth_en += length * step;
    const double scale_error = errors.scale_sigma * gauss(rng);
    const double drift = RadFromDeg(errors.heading_drift_sigma_deg) * gauss(rng);
    heading_error += drift;
    const Eigen::Rotation2Dd error_rotation(-heading_error);  // Clockwise heading error.
    measured_en += (1.0 + scale_error) * (error_rotation * (length * step));
    t.leg_scale_errors.push_back(scale_error);
    t.leg_heading_errors.push_back(drift);
    t.truth.push_back({site, Eigen::Vector3d(truth_en.y(), truth_en.x(), 0.0), heading});
    t.telemetry.push_back(
        {site, Eigen::Vector3d(measured_en.y(), measured_en.x(), 0.0), heading + heading_error});
  }
  return t;
}

std::pair<double, double> LandingSite(std::string_view name) {
  if (name == "gusev") return {-14.5692, 175.4729};     // Spirit (MER-A).
  if (name == "meridiani") return {-1.9462, 354.4734};  // Opportunity (MER-B).
  throw Error("unknown landing site '" + std::string(name) + "': expected gusev or meridiani");
}

MissionOptions MissionOptions::Preset(std::string_view name) {
  MissionOptions o;
  o.preset = std::string(name);
  if (name == "demo") {
    o.scene.half_extent_m = 160.0;
    o.scene.crater_count = 10;
    o.scene.crater_max_diameter_m = 60.0;
    o.scene.rock_corridor_m = 30.0;
    o.traverse.site_count = 5;
    return o;
  }
  if (name == "long") {
    o.scene.half_extent_m = 700.0;
    o.scene.crater_count = 40;
    o.scene.crater_max_diameter_m = 150.0;  // Up to Endurance size (Table 2.2).
    o.scene.roughness_wavelength_m = 120.0;
    o.scene.rock_corridor_m = 30.0;
    o.scene.max_rocks = 250000;  // ~48 000 at k = 0.05; room for rockier fields.
    o.orbital.supersample = 1;
    o.traverse.site_count = 46;  // 45 legs of 20-30 m: ~1.1 km.
    o.traverse.min_leg_m = 20.0;
    o.traverse.max_leg_m = 30.0;
    o.second_sun_image = true;
    o.ctx_image = true;
    return o;
  }
  throw Error("unknown preset '" + std::string(name) + "': expected demo or long");
}

void MissionOptions::Check() const {
  RequireOption(std::abs(site_lat_deg) < 80.0, "MissionOptions.site_lat_deg", "|lat| < 80 degrees");
  RequireOption(std::isfinite(site_lon_deg), "MissionOptions.site_lon_deg", "a finite longitude");
  RequireOption(orbital_dtm_posting_m >= orbital.gsd_m, "MissionOptions.orbital_dtm_posting_m",
                ">= the orbital GSD");
  scene.Check();
  orbital.Check();
  traverse.Check();
  // A longer leg would leave the scene from its centre (PlanTraverse turns back at 3/4 of it).
  RequireOption(traverse.max_leg_m <= 0.75 * scene.half_extent_m,
                "MissionOptions.traverse.max_leg_m",
                "at most 3/4 of scene.half_extent_m (" +
                    std::to_string(0.75 * scene.half_extent_m) + " m for this preset) [m]");
  telemetry.Check();
  navcam.Check();
  render.Check();
  pancam.Check();
  RequireOption(navcam_pairs >= 0 && navcam_pairs <= 64, "MissionOptions.navcam_pairs", "0..64");
  RequireOption(pancam_pairs >= 0 && pancam_pairs <= 64, "MissionOptions.pancam_pairs", "0..64");
  RequireOption(pancam_elevation_deg > -90.0 && pancam_elevation_deg < 90.0,
                "MissionOptions.pancam_elevation_deg", "in (-90, 90) degrees");
  RequireOption(navcam_elevation_deg > -90.0 && navcam_elevation_deg < 90.0,
                "MissionOptions.navcam_elevation_deg", "in (-90, 90) degrees");
}

namespace {

void CreateMissionFolders(const std::filesystem::path& out_dir) {
  for (const char* sub : {"", "orbital", "truth", "telemetry", "sites"}) {
    std::error_code ec;
    std::filesystem::create_directories(out_dir / sub, ec);
    if (ec) throw Error((out_dir / sub).string() + ": cannot create folder: " + ec.message());
  }
}

// The mission's scene: the preset's terrain, with rocks along the true traverse.
SceneOptions MissionSceneOptions(const MissionOptions& options, const Traverse& traverse) {
  SceneOptions scene_options = options.scene;
  scene_options.seed = options.seed;
  for (const SitePose& s : traverse.truth) {
    scene_options.rock_path.emplace_back(s.position.y(), s.position.x());  // (east, north)
  }
  return scene_options;
}

// The scene's ENU origin: the landing site, on the ground.
SceneGeoreference MissionGeoreference(const MissionOptions& options, const Scene& scene) {
  SceneGeoreference georef;
  georef.origin = Geographic{RadFromDeg(options.site_lat_deg), RadFromDeg(options.site_lon_deg),
                             scene.GroundHeightAt(0.0, 0.0)};
  return georef;
}

// `progress` rescaled so that a stage's [0, 1] reports as [from, to] of the whole.
ProgressCallback ProgressRange(const ProgressCallback& progress, double from, double to) {
  return [&progress, from, to](double f, std::string_view name) {
    return progress ? progress(from + (to - from) * f, name) : true;
  };
}

nlohmann::json OrbitalEntry(const std::string& id, const std::string& kind, const std::string& path,
                            double gsd, const OrbitalImageOptions* o) {
  nlohmann::json j = {{"id", id}, {"kind", kind}, {"path", path}, {"gsd_m", gsd}};
  if (o != nullptr) {
    j["sun_azimuth_deg"] = o->sun_azimuth_deg;
    j["sun_elevation_deg"] = o->sun_elevation_deg;
    j["bits"] = o->bits;
  }
  return j;
}

// The orthoimage again, under another sun.
OrbitalImageOptions SecondSunImageOptions(const MissionOptions& options) {
  OrbitalImageOptions other = options.orbital;
  other.sun_azimuth_deg = std::fmod(options.orbital.sun_azimuth_deg + 140.0, 360.0);
  other.sun_elevation_deg = 45.0;
  other.seed = options.seed + 101u;
  return other;
}

// A CTX-like coarse image: 6 m pixels, 8 bits.
OrbitalImageOptions CtxImageOptions(const MissionOptions& options) {
  OrbitalImageOptions ctx = options.orbital;
  ctx.gsd_m = 6.0;
  ctx.supersample = 4;
  ctx.mtf_sigma_px = 0.6;
  ctx.bits = 8;
  ctx.full_well_dn = 200.0;
  ctx.seed = options.seed + 202u;
  return ctx;
}

struct OrbitalStage {
  OrbitalProducts hirise;                            // The main orthoimage and DTM.
  nlohmann::json entries = nlohmann::json::array();  // The manifest's "orbital" list.
};

// Renders and writes the orbital products: the HiRISE-like image and DTM, and optionally the
// image under a second sun and a CTX-like image.
OrbitalStage WriteOrbitalProducts(const MissionOptions& options, const Scene& scene,
                                  const SceneGeoreference& georef,
                                  const std::filesystem::path& out_dir,
                                  const ProgressCallback& progress) {
  OrbitalStage out;
  const double half = options.scene.half_extent_m;
  out.hirise = RenderOrbitalProducts(scene, georef, half, options.orbital_dtm_posting_m,
                                     options.orbital, ProgressRange(progress, 0.05, 0.3));
  WriteGeoTiff(out_dir / "orbital/hirise_ortho.tif", out.hirise.image);
  WriteGeoTiff(out_dir / "orbital/hirise_dtm.tif", out.hirise.dtm);
  out.entries.push_back(OrbitalEntry("hirise", "image", "orbital/hirise_ortho.tif",
                                     options.orbital.gsd_m, &options.orbital));
  out.entries.push_back(OrbitalEntry("hirise_dtm", "dtm", "orbital/hirise_dtm.tif",
                                     options.orbital_dtm_posting_m, nullptr));
  if (options.second_sun_image) {
    const OrbitalImageOptions other = SecondSunImageOptions(options);
    const OrbitalProducts second =
        RenderOrbitalProducts(scene, georef, half, options.orbital_dtm_posting_m, other,
                              ProgressRange(progress, 0.3, 0.4));
    WriteGeoTiff(out_dir / "orbital/hirise_ortho_sun2.tif", second.image);
    out.entries.push_back(
        OrbitalEntry("hirise_sun2", "image", "orbital/hirise_ortho_sun2.tif", other.gsd_m, &other));
  }
  if (options.ctx_image) {
    const OrbitalImageOptions ctx = CtxImageOptions(options);
    const OrbitalProducts coarse =
        RenderOrbitalProducts(scene, georef, half, 6.0, ctx, ProgressRange(progress, 0.4, 0.45));
    WriteGeoTiff(out_dir / "orbital/ctx_ortho.tif", coarse.image);
    out.entries.push_back(OrbitalEntry("ctx", "image", "orbital/ctx_ortho.tif", 6.0, &ctx));
  }
  return out;
}

// Where the rover stands at a site: its true pose (to render from) and the orientation the
// telemetry believes (for the labels).
struct RoverPoseAtSite {
  Eigen::Vector3d site_in_enu;
  Rigid3d enu_from_rover;
  Rigid3d believed_site_from_rover;
};

RoverPoseAtSite RoverPoseAt(const Scene& scene, const SitePose& truth, const SitePose& telemetry) {
  const Rigid3d site_from_enu_axes = SiteFromEnu();  // Axis permutation (N, E, D) <- (E, N, U).
  RoverPoseAtSite pose;
  pose.site_in_enu = Eigen::Vector3d(truth.position.y(), truth.position.x(),
                                     scene.GroundHeightAt(truth.position.y(), truth.position.x()));
  const Rigid3d enu_from_site(site_from_enu_axes.rotation.conjugate(), pose.site_in_enu);
  pose.enu_from_rover =
      enu_from_site * Rigid3d(SiteFromRoverRotation(truth.heading), Eigen::Vector3d::Zero());
  pose.believed_site_from_rover =
      Rigid3d(SiteFromRoverRotation(telemetry.heading), Eigen::Vector3d::Zero());
  return pose;
}

struct RoverImagesStage {
  nlohmann::json sites = nlohmann::json::array();  // The manifest's "sites" list.
  int image_count = 0;
};

// Rover images: a Navcam (and optionally Pancam) panorama per site, rendered from the true pose;
// the labels carry the telemetry heading, as flight products carry the onboard estimate.
RoverImagesStage RenderRoverImages(const MissionOptions& options, const Scene& scene,
                                   const Traverse& traverse, const std::filesystem::path& out_dir,
                                   const ProgressCallback& progress) {
  RoverImagesStage out;
  RenderOptions render = options.render;
  render.sun_azimuth_deg = options.orbital.sun_azimuth_deg;
  render.sun_elevation_deg = options.orbital.sun_elevation_deg;
  const std::vector<Instrument> instruments = {
      {&options.navcam, Panorama(options.navcam_pairs, RadFromDeg(options.navcam_elevation_deg))},
      {&options.pancam, Panorama(options.pancam_pairs, RadFromDeg(options.pancam_elevation_deg))}};
  for (size_t k = 0; k < traverse.truth.size(); ++k) {
    ReportProgress(progress,
                   0.45 + 0.5 * static_cast<double>(k) / static_cast<double>(traverse.truth.size()),
                   "rover images");
    const SitePose& truth = traverse.truth[k];
    char folder_name[32];
    std::snprintf(folder_name, sizeof(folder_name), "sites/site_%03d", truth.site);
    std::filesystem::create_directories(out_dir / folder_name);
    nlohmann::json images = nlohmann::json::array();
    if (options.navcam_pairs + options.pancam_pairs > 0) {
      const RoverPoseAtSite pose = RoverPoseAt(scene, truth, traverse.telemetry[k]);
      const SiteMesh mesh(scene, pose.site_in_enu, render);
      for (const Instrument& instrument : instruments) {
        if (instrument.pointings.empty()) continue;
        const std::vector<nlohmann::json> entries =
            RenderPanorama(mesh, instrument, pose.enu_from_rover, pose.believed_site_from_rover,
                           truth.site, out_dir, folder_name, render.bits,
                           options.seed * 7919u + static_cast<uint32_t>(k * 1000));
        for (const auto& entry : entries) images.push_back(entry);
        out.image_count += static_cast<int>(entries.size());
      }
    }
    out.sites.push_back({{"site", truth.site}, {"images", images}});
  }
  return out;
}

// Planetocentric coordinates of a point given in the scene's ENU frame.
Geographic GeographicOfEnu(const SceneGeoreference& georef, const Rigid3d& mbf_from_enu,
                           double east, double north, double up) {
  return GeographicFromMbf(georef.body, mbf_from_enu * Eigen::Vector3d(east, north, up));
}

// truth/craters.csv: each crater in ENU, geographic and orbital image pixel coordinates.
std::string CraterTable(const Scene& scene, const SceneGeoreference& georef,
                        const GeoTransform& image_transform) {
  const MapProjection projection = georef.Projection();
  const Rigid3d mbf_from_enu = georef.EnuFromMbf().Inverse();
  CsvTable craters;
  craters.Row({"id", "east_m", "north_m", "lat_deg", "lon_deg", "col_px", "row_px", "semi_major_m",
               "semi_minor_m", "angle_deg", "depth_m", "rim_height_m", "floor_fraction",
               "flat_floor"});
  for (const Crater& c : scene.craters()) {
    const Geographic g = GeographicOfEnu(georef, mbf_from_enu, c.center.x(), c.center.y(), 0.0);
    const Spherical radial =
        SphericalFromMbf(mbf_from_enu * Eigen::Vector3d(c.center.x(), c.center.y(), 0.0));
    const Eigen::Vector2d map = projection.Forward({radial.lat, radial.lon, 0.0});
    const Eigen::Vector2d pixel = image_transform.MapToPixel(map.x(), map.y());
    craters.Row({std::to_string(c.id), Fixed(c.center.x(), 4), Fixed(c.center.y(), 4),
                 Fixed(DegFromRad(g.lat), 9), Fixed(DegFromRad(g.lon), 9), Fixed(pixel.x(), 3),
                 Fixed(pixel.y(), 3), Fixed(c.semi_major, 4), Fixed(c.semi_minor, 4),
                 Fixed(DegFromRad(c.angle), 4), Fixed(c.depth, 4), Fixed(c.rim_height, 4),
                 Fixed(c.floor_fraction, 4), c.flat_floor ? "1" : "0"});
  }
  return craters.text;
}

// truth/rocks.csv: every rock's shape and placement.
std::string RockTable(const Scene& scene) {
  CsvTable rocks;
  rocks.Row({"id", "shape", "east_m", "north_m", "ground_z_m", "height_m", "a_m", "b_m",
             "azimuth_deg", "tilt_x_deg", "tilt_y_deg"});
  for (const Rock& r : scene.rocks()) {
    rocks.Row({std::to_string(r.id), ToString(r.shape), Fixed(r.center.x(), 4),
               Fixed(r.center.y(), 4), Fixed(r.ground_z, 4), Fixed(r.height, 4), Fixed(r.a, 4),
               Fixed(r.b, 4), Fixed(DegFromRad(r.azimuth), 3), Fixed(DegFromRad(r.tilt_x), 3),
               Fixed(DegFromRad(r.tilt_y), 3)});
  }
  return rocks.text;
}

// A site poses table (truth/sites.csv with geographic coordinates, telemetry/sites.csv without).
// Heights come from the terrain under the true sites (telemetry's vertical, from the
// inclinometers, is taken as exact; its horizontal error is what the model describes).
std::string SiteTable(const std::vector<SitePose>& poses, bool with_geographic,
                      const Traverse& traverse, const Scene& scene,
                      const SceneGeoreference& georef) {
  const double ground_z0 = georef.origin.h;
  const Rigid3d mbf_from_enu = georef.EnuFromMbf().Inverse();
  CsvTable table;
  std::vector<std::string> header = {"site", "north_m", "east_m", "down_m", "heading_deg"};
  if (with_geographic) header.insert(header.end(), {"lat_deg", "lon_deg", "h_m"});
  table.Row(header);
  for (const SitePose& s : poses) {
    const SitePose& truth = traverse.truth[static_cast<size_t>(s.site)];
    const double east = s.position.y(), north = s.position.x();
    const double up = scene.GroundHeightAt(truth.position.y(), truth.position.x());
    // Site 0's frame: origin on the ground at the ENU origin.
    const Eigen::Vector3d in_site = SiteFromEnu() * Eigen::Vector3d(east, north, up - ground_z0);
    std::vector<std::string> row = {
        std::to_string(s.site), Fixed(in_site.x(), 4), Fixed(in_site.y(), 4), Fixed(in_site.z(), 4),
        Fixed(DegFromRad(WrapLongitude(s.heading, LongitudeDomain::kZeroTo360)), 4)};
    if (with_geographic) {
      const Geographic g = GeographicOfEnu(georef, mbf_from_enu, east, north, up - ground_z0);
      row.insert(row.end(),
                 {Fixed(DegFromRad(g.lat), 10), Fixed(DegFromRad(g.lon), 10), Fixed(g.h, 4)});
    }
    table.Row(row);
  }
  return table.text;
}

void WriteTruthTables(const Scene& scene, const Traverse& traverse, const SceneGeoreference& georef,
                      const GeoTransform& image_transform, const std::filesystem::path& out_dir) {
  const std::string craters = CraterTable(scene, georef, image_transform);
  const std::string rocks = RockTable(scene);
  WriteFileAtomically(out_dir / "truth/craters.csv", craters);
  WriteFileAtomically(out_dir / "truth/rocks.csv", rocks);
  WriteFileAtomically(out_dir / "truth/sites.csv",
                      SiteTable(traverse.truth, true, traverse, scene, georef));
  WriteFileAtomically(out_dir / "telemetry/sites.csv",
                      SiteTable(traverse.telemetry, false, traverse, scene, georef));
}

MissionSummary Summarize(const Traverse& traverse, const Scene& scene,
                         const OrbitalProducts& hirise, int rover_images) {
  MissionSummary summary;
  summary.site_count = static_cast<int>(traverse.truth.size());
  summary.crater_count = static_cast<int>(scene.craters().size());
  summary.rock_count = static_cast<int>(scene.rocks().size());
  for (size_t i = 1; i < traverse.truth.size(); ++i) {
    summary.traverse_length_m +=
        (traverse.truth[i].position - traverse.truth[i - 1].position).head<2>().norm();
  }
  summary.final_telemetry_error_m =
      (traverse.truth.back().position - traverse.telemetry.back().position).head<2>().norm();
  summary.orbital_size_px = hirise.image.bands.front().cols;
  summary.rover_images = rover_images;
  return summary;
}

// mission.json (docs/mission-format.md).
nlohmann::json MissionManifestJson(const MissionOptions& options, const SceneGeoreference& georef,
                                   const nlohmann::json& orbital, const nlohmann::json& sites) {
  return {
      {"format", "areomap-mission"},
      {"version", 1},
      {"name", "synthetic-" + options.preset + "-seed" + std::to_string(options.seed)},
      {"body", {{"name", georef.body.name}, {"a_m", georef.body.a}, {"b_m", georef.body.b}}},
      {"origin",
       {{"lat_deg", options.site_lat_deg},
        {"lon_deg", options.site_lon_deg},
        {"h_m", georef.origin.h},
        {"latitude", "planetocentric"},
        {"longitude", "east"}}},
      {"site_frame", "MER site frame of site 0: x north, y east, z down [m], origin = origin"},
      {"orbital", orbital},
      {"sites", sites},
      {"telemetry",
       {{"sites", "telemetry/sites.csv"},
        {"model",
         {{"scale_sigma", options.telemetry.scale_sigma},
          {"heading_drift_sigma_deg", options.telemetry.heading_drift_sigma_deg}}}}},
      {"truth",
       {{"craters", "truth/craters.csv"},
        {"rocks", "truth/rocks.csv"},
        {"sites", "truth/sites.csv"},
        {"dtm", "orbital/hirise_dtm.tif"}}},
  };
}

}  // namespace

MissionSummary GenerateMission(const MissionOptions& options, const std::filesystem::path& out_dir,
                               const ProgressCallback& progress) {
  options.Check();
  CreateMissionFolders(out_dir);
  ReportProgress(progress, 0.0, "traverse");
  const Traverse traverse =
      PlanTraverse(options.traverse, options.telemetry, options.scene.half_extent_m, options.seed);
  ReportProgress(progress, 0.02, "scene");
  const Scene scene(MissionSceneOptions(options, traverse));
  const SceneGeoreference georef = MissionGeoreference(options, scene);
  const OrbitalStage orbital = WriteOrbitalProducts(options, scene, georef, out_dir, progress);
  const RoverImagesStage rover = RenderRoverImages(options, scene, traverse, out_dir, progress);
  ReportProgress(progress, 0.95, "truth");
  WriteTruthTables(scene, traverse, georef, orbital.hirise.image.geotransform, out_dir);
  MissionSummary summary = Summarize(traverse, scene, orbital.hirise, rover.image_count);
  summary.manifest = out_dir / "mission.json";
  WriteFileAtomically(
      summary.manifest,
      MissionManifestJson(options, georef, orbital.entries, rover.sites).dump(2) + "\n");
  ReportProgress(progress, 1.0, "done");
  return summary;
}

}  // namespace areomap
