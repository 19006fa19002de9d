// Rover stereo cameras and image rendering for the mission generator.
//
// Frames: MER rover frame (x forward, y right, z down; origin on the ground under the rover's
// centre), MER site frame (x north, y east, z down; origin on the ground at the site), and the
// scene's local ENU frame (flat within the scene: its curvature, ~30 urad per 100 m, is
// neglected). Camera models are CAHVOR in the rover frame, as MER products carry them.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/map/cahvor.h"
#include "areomap/map/progress.h"
#include "areomap/map/rigid3d.h"
#include "areomap/samples/scene.h"

namespace areomap {

// A stereo camera head on the mast (Table 1.1 defaults: Navcam).
struct StereoCameraOptions {
  std::string name = "NAVCAM";
  int width = 1024;   // [px]
  int height = 1024;  // [px]
  double focal_length_mm = 14.67;
  double pixel_pitch_um = 12.0;    // MER CCD.
  double field_of_view_deg = 0.0;  // Horizontal FOV [deg]; if > 0 it sets the focal length.
  double baseline_m = 0.20;
  Eigen::Vector3d mast_head_in_rover{0.45, 0.0, -1.5};              // Between the two cameras [m].
  Eigen::Vector3d radial_distortion{0.00096, -0.002183, 0.018547};  // CAHVOR R (real Navcam).
  void Check() const;  // Throws areomap::Error naming the field; FOV must be < 180 deg.
  double FieldOfViewDeg() const;
  double FocalLengthPx() const;
};

// Table 1.1 Pancam: 16.8 deg field of view (43 mm on 12 um pixels), 30 cm baseline.
StereoCameraOptions PancamOptions();

// One pointing of the stereo head: azimuth clockwise from the rover's forward axis and
// elevation above the rover's horizontal plane (negative = looking down) [rad].
struct StereoPointing {
  double azimuth = 0.0;
  double elevation = 0.0;
};

// CAHVOR models of the left (index 0) and right (1) cameras in the rover frame.
std::array<CahvorModel, 2> StereoCameras(const StereoCameraOptions& options,
                                         const StereoPointing& pointing);

// A panorama: `pairs` pointings evenly spread in azimuth at one elevation.
std::vector<StereoPointing> Panorama(int pairs, double elevation);

struct RenderOptions {
  double sun_azimuth_deg = 120.0;
  double sun_elevation_deg = 30.0;
  double ambient = 0.12;
  double sky_radiance = 0.10;
  double near_posting_m = 0.02;  // Mesh posting within `near_radius_m` (rocks need <= 2 cm).
  double near_radius_m = 8.0;
  double mid_posting_m = 0.08;
  double mid_radius_m = 32.0;
  double far_posting_m = 0.5;  // Out to `far_radius_m` (within the scene).
  double far_radius_m = 160.0;
  double full_well_dn = 3500.0;  // DN of albedo 0.5 at normal incidence.
  double read_noise_dn = 2.0;
  int bits = 12;
  void Check() const;
};

// A site's terrain as a triangle mesh in three rings of decreasing resolution, shaded once
// (Lambert, sun, cast shadows) and then rendered into any number of cameras.
class SiteMesh {
 public:
  // `site_in_enu`: the site origin (on the ground) in the scene's ENU frame.
  SiteMesh(const Scene& scene, const Eigen::Vector3d& site_in_enu, const RenderOptions& options);

  struct Image {
    cv::Mat dn;     // CV_16U, `bits` deep, with noise.
    cv::Mat range;  // CV_32F distance from the camera centre [m]; NaN for sky.
  };
  // Renders a camera given in ENU. `seed` drives the sensor noise.
  Image Render(const CahvorModel& camera_in_enu, int width, int height, uint32_t seed) const;

 private:
  struct Level {
    double posting = 0.0;
    int size = 0;                         // Vertices per side.
    Eigen::Vector2d origin;               // ENU (x, y) of vertex (0, 0) (south-west corner).
    std::vector<Eigen::Vector3f> points;  // ENU, row-major from the south.
    std::vector<float> radiance;
    double inner_half = 0.0;  // Cells entirely inside this square are drawn by the finer level.
  };
  std::vector<Level> levels_;
  Eigen::Vector3d center_;
  RenderOptions options_;
};

}  // namespace areomap
