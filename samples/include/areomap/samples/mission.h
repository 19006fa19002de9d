// The synthetic mission generator: scene, orbital products, traverse with telemetry, and the
// ground truth, written as a mission folder (docs/mission-format.md).
//
// Frames: positions of sites are given in the MER site frame of the first site (x north,
// y east, z down, origin on the ground at site 0), like MER telemetry; the scene's local ENU
// frame has the same origin. Deterministic: the same options give byte-identical files.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "areomap/map/progress.h"
#include "areomap/samples/orbital.h"
#include "areomap/samples/rover.h"
#include "areomap/samples/scene.h"

namespace areomap {

struct TraverseOptions {
  int site_count = 5;       // Sites (panoramas), the first at the origin.
  double min_leg_m = 15.0;  // Leg length range [m] (ch. 4: legs of 20-30 m typical).
  double max_leg_m = 25.0;
  double max_turn_deg = 35.0;  // Largest heading change between legs [deg].
  void Check() const;
};

// Dead-reckoning error per leg: the measured leg is the true one scaled by (1 + s) and rotated
// by the accumulated heading error, s ~ N(0, scale_sigma), heading error += N(0, drift_sigma).
// With the defaults a 25 m leg is off by ~1.3 m along track and the drift grows across track;
// after a few legs the error approaches the ~10 % of distance seen at Silver Lake (ch. 4).
struct TelemetryErrorModel {
  double scale_sigma = 0.05;           // Relative leg-length error, 1 sigma.
  double heading_drift_sigma_deg = 2;  // Heading error added per leg, 1 sigma [deg].
  void Check() const;
};

struct SitePose {
  int site = 0;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  // In site 0's frame (N, E, D) [m].
  double heading = 0.0;                                // Rover yaw, clockwise from north [rad].
};

struct Traverse {
  std::vector<SitePose> truth;
  std::vector<SitePose> telemetry;
  std::vector<double> leg_scale_errors;    // s per leg (truth of the error model).
  std::vector<double> leg_heading_errors;  // Heading error increment per leg [rad].
};

// Plans a traverse that stays inside the square of half side `half_extent_m` (ENU, 2D; z is
// filled in later from the terrain). Throws areomap::Error for invalid options.
Traverse PlanTraverse(const TraverseOptions& options, const TelemetryErrorModel& errors,
                      double half_extent_m, uint32_t seed);

// Planetocentric latitude and east longitude [deg] of a MER landing site: "gusev" (Spirit) or
// "meridiani" (Opportunity). Throws areomap::Error for other names.
std::pair<double, double> LandingSite(std::string_view name);

struct MissionOptions {
  std::string preset = "demo";
  uint32_t seed = 1;
  double site_lat_deg = -14.5692;  // Planetocentric latitude of site 0 [deg] (Gusev).
  double site_lon_deg = 175.4729;  // East longitude of site 0 [deg].
  SceneOptions scene;
  OrbitalImageOptions orbital;
  double orbital_dtm_posting_m = 1.0;
  bool second_sun_image = false;  // Also render the orthoimage under another sun.
  bool ctx_image = false;         // Also a CTX-like 6 m image.
  TraverseOptions traverse;
  TelemetryErrorModel telemetry;
  StereoCameraOptions navcam;         // Table 1.1 Navcam.
  int navcam_pairs = 10;              // Stereo pairs per site panorama (0 = no rover images).
  double navcam_elevation_deg = -25;  // Panorama tilt [deg] (negative = down).
  StereoCameraOptions pancam = PancamOptions();  // Table 1.1 Pancam.
  int pancam_pairs = 0;               // Pancam stereo pairs per site (a full pan is ~27).
  double pancam_elevation_deg = -12;  // Pancam panorama tilt [deg].
  RenderOptions render;               // Mesh postings, sensor; the sun is the orbital one.

  // "demo" (small, about a minute) or "long" (~1.1 km traverse like the dissertation's test).
  // Throws areomap::Error naming the accepted presets.
  static MissionOptions Preset(std::string_view name);
  void Check() const;
};

struct MissionSummary {
  std::filesystem::path manifest;
  int site_count = 0;
  int crater_count = 0;
  int rock_count = 0;
  double traverse_length_m = 0.0;
  double final_telemetry_error_m = 0.0;
  int orbital_size_px = 0;
  int rover_images = 0;
};

// The label of a synthetic rover image, laid out like the PDS3 label JSON GDAL gives for MER
// products (GEOMETRIC_CAMERA_MODEL and ROVER_COORDINATE_SYSTEM groups), so ParseProductGeometry
// reads both. `site_from_rover` is what the rover believed (telemetry heading).
nlohmann::json RoverImageLabel(const std::string& instrument_id, int site,
                               const CahvorModel& camera_in_rover, const Rigid3d& site_from_rover,
                               int width, int height, int bits);

// Generates the mission into `out_dir` (created if needed). Every file is written atomically.
MissionSummary GenerateMission(const MissionOptions& options, const std::filesystem::path& out_dir,
                               const ProgressCallback& progress = nullptr);

}  // namespace areomap
