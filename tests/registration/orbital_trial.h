// Generated orbital-ground registration trials: a synthetic scene rendered as a HiRISE-like
// orbital image (0.25 m, the mission's sun) and as a rover orthophoto (finer GSD, another sun,
// masked to the fan a rover's stereo panorama covers, georeferenced with a known telemetry
// error), plus a decoy orbital image of another scene on the same grid.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <optional>
#include <random>
#include <vector>

#include <Eigen/Core>
#include <opencv2/imgproc.hpp>

#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_image.h"
#include "areomap/registration/orbital_match.h"
#include "areomap/samples/orbital.h"
#include "areomap/samples/scene.h"

namespace areomap::testing {

struct TrialOptions {
  uint32_t seed = 1;
  double ortho_gsd_m = 0.1;
  double ortho_half_extent_m = 25.0;  // The ortho render covers +-this around the rover [m].
  double orbital_half_extent_m = 50.0;
  int orbital_supersample = 1;     // 2 renders finer but costs 4x.
  double telemetry_sigma_m = 4.0;  // Telemetry error per axis, 1 sigma [m].
  double heading_error_deg = 0.0;  // Rotation of the ortho's georeference about the rover.
  double fan_fov_deg = 0.0;        // The rover's view: 0 = a random 120-240 deg fan.
  bool decoy = true;
  // Resolution falls with range in a rover orthophoto: a Navcam pixel (0.76 mrad) seen from
  // the mast (1.5 m) covers r^2 IFOV / h metres of ground along the line of sight, 0.3 m at
  // 25 m. Modelled as an isotropic Gaussian of half that footprint (1 sigma), in range bands.
  bool range_blur = true;
};

struct Trial {
  OrthoImage ortho;
  std::optional<OrbitalImage> orbital;
  std::optional<OrbitalImage> decoy;  // When TrialOptions::decoy.
  std::optional<OrbitalImage> dtm;    // The orbital DTM (1 m posting).
  GeoTransform ortho_truth;           // The ortho's true georeference.
  OrbitalPrior prior;
  Eigen::Vector2d telemetry_error_en_m;  // Where telemetry put the rover minus the truth [m].
  double gsd_m = 0.25;
};

inline Scene TrialScene(uint32_t seed) {
  SceneOptions options;
  options.half_extent_m = 160.0;
  options.crater_count = 6;
  options.crater_min_diameter_m = 6.0;
  options.crater_max_diameter_m = 40.0;
  options.rock_path = {Eigen::Vector2d(-100, -20), Eigen::Vector2d(100, 20)};
  options.rock_corridor_m = 40.0;
  options.rock_abundance_k = 0.03;
  options.seed = seed;
  return Scene(options);
}

// A rover's view: a fan of `fov_deg` around `azimuth_deg` (clockwise from north) between 2 m
// and `max_range_m`, minus a few random occlusion blobs.
inline cv::Mat RoverFanMask(cv::Size size, double gsd_m, double azimuth_deg, double fov_deg,
                            double max_range_m, std::mt19937& rng) {
  cv::Mat mask(size, CV_8U, cv::Scalar(0));
  const double cx = size.width / 2.0, cy = size.height / 2.0;
  for (int r = 0; r < size.height; ++r) {
    for (int c = 0; c < size.width; ++c) {
      const double east = (c + 0.5 - cx) * gsd_m, north = (cy - r - 0.5) * gsd_m;
      const double range = std::hypot(east, north);
      double az = std::atan2(east, north) * 180.0 / std::numbers::pi - azimuth_deg;
      az = std::remainder(az, 360.0);
      if (range >= 2.0 && range <= max_range_m && std::abs(az) <= fov_deg / 2.0) {
        mask.at<uchar>(r, c) = 255;
      }
    }
  }
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 6; ++k) {  // Occlusions behind rocks and ridges.
    const cv::Point centre(static_cast<int>(u(rng) * size.width),
                           static_cast<int>(u(rng) * size.height));
    const int radius = static_cast<int>((1.0 + 2.0 * u(rng)) / gsd_m);
    cv::circle(mask, centre, radius, cv::Scalar(0), cv::FILLED);
  }
  return mask;
}

// See TrialOptions::range_blur. The rover stands at the image centre.
inline void BlurWithRange(cv::Mat& image, double gsd_m) {
  constexpr double kIfov = 0.76e-3, kMastHeight = 1.5;
  const cv::Mat sharp = image.clone();
  const double cx = image.cols / 2.0, cy = image.rows / 2.0;
  const double max_range = std::hypot(cx, cy) * gsd_m;
  constexpr int kBands = 6;
  std::vector<cv::Mat> blurred;
  std::vector<double> band_range;
  for (int b = 0; b <= kBands; ++b) {
    const double r = max_range * b / kBands;
    const double sigma_px = 0.5 * r * r * kIfov / kMastHeight / gsd_m;
    cv::Mat out = sharp.clone();
    if (sigma_px > 0.3) cv::GaussianBlur(sharp, out, cv::Size(), sigma_px, sigma_px);
    blurred.push_back(out);
    band_range.push_back(r);
  }
  for (int r = 0; r < image.rows; ++r) {
    for (int c = 0; c < image.cols; ++c) {
      const double range = std::hypot(c + 0.5 - cx, r + 0.5 - cy) * gsd_m;
      const double t = std::min(range / max_range * kBands, kBands - 1e-9);
      const int b = static_cast<int>(t);
      const double f = t - b;
      image.at<float>(r, c) = static_cast<float>((1 - f) * blurred[b].at<float>(r, c) +
                                                 f * blurred[b + 1].at<float>(r, c));
    }
  }
}

inline Trial MakeTrial(const TrialOptions& o) {
  std::mt19937 rng(o.seed * 7919u + 13u);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  SceneGeoreference georef;
  georef.origin = {RadFromDeg(-14.5692), RadFromDeg(175.4729), -1900.0};
  const Scene scene = TrialScene(o.seed);

  Trial trial;
  OrbitalImageOptions orbital;
  orbital.gsd_m = trial.gsd_m;
  orbital.seed = o.seed;
  orbital.supersample = o.orbital_supersample;
  const OrbitalProducts products =
      RenderOrbitalProducts(scene, georef, o.orbital_half_extent_m, 1.0, orbital);
  trial.orbital = OrbitalImage::FromGeoRaster(products.image, "orbital");
  trial.dtm = OrbitalImage::FromGeoRaster(products.dtm, "dtm");
  if (o.decoy) {
    const Scene other = TrialScene(o.seed + 100000u);
    trial.decoy = OrbitalImage::FromGeoRaster(
        RenderOrbitalProducts(other, georef, o.orbital_half_extent_m, 1.0, orbital).image, "decoy");
  }

  // The orthophoto: another sun (rover images are taken at another time of day), finer GSD.
  OrbitalImageOptions rover;
  rover.gsd_m = o.ortho_gsd_m;
  rover.sun_azimuth_deg = 120.0 + 120.0 * (u(rng) - 0.5);
  rover.sun_elevation_deg = 25.0 + 35.0 * u(rng);
  rover.supersample = 1;
  rover.mtf_sigma_px = 0.7;
  rover.read_noise_dn = 3.0;
  rover.seed = o.seed + 17u;
  const OrbitalProducts render =
      RenderOrbitalProducts(scene, georef, o.ortho_half_extent_m, 1.0, rover);
  trial.ortho.source = "ortho";
  render.image.bands[0].convertTo(trial.ortho.image, CV_32F);
  if (o.range_blur) BlurWithRange(trial.ortho.image, o.ortho_gsd_m);
  // Drawn in the order GCC evaluated them as two arguments of one call (the last first), so the
  // trials stay those the tests were written on.
  const double random_fov_deg = 120.0 + 120.0 * u(rng);
  const double fan_azimuth_deg = 360.0 * u(rng);
  trial.ortho.mask = RoverFanMask(trial.ortho.image.size(), o.ortho_gsd_m, fan_azimuth_deg,
                                  o.fan_fov_deg > 0.0 ? o.fan_fov_deg : random_fov_deg,
                                  o.ortho_half_extent_m, rng);
  trial.ortho.crs_wkt = render.image.crs_wkt;

  // Telemetry error: the georeference is translated by the error and rotated by the heading
  // error about the rover (the image centre).
  trial.telemetry_error_en_m = o.telemetry_sigma_m * Eigen::Vector2d(gauss(rng), gauss(rng));
  const GeoTransform& truth = render.image.geotransform;
  trial.ortho_truth = truth;
  const double cx = trial.ortho.image.cols / 2.0, cy = trial.ortho.image.rows / 2.0;
  const Eigen::Vector2d rover_map = truth.PixelToMap(cx, cy);
  const double h = o.heading_error_deg * std::numbers::pi / 180.0;
  Eigen::Matrix2d linear;
  linear << truth.c[1], truth.c[2], truth.c[4], truth.c[5];
  Eigen::Matrix2d rot;
  rot << std::cos(h), -std::sin(h), std::sin(h), std::cos(h);  // CCW on the map.
  const Eigen::Matrix2d shifted_linear = rot * linear;
  const Eigen::Vector2d origin =
      rover_map + trial.telemetry_error_en_m - shifted_linear * Eigen::Vector2d(cx, cy);
  trial.ortho.geotransform.c = {origin.x(), shifted_linear(0, 0), shifted_linear(0, 1),
                                origin.y(), shifted_linear(1, 0), shifted_linear(1, 1)};
  const PixelGrid grid(trial.ortho.geotransform, trial.ortho.crs_wkt, "ortho");
  trial.prior.position = *grid.PixelToGeographic({cx, cy});
  trial.prior.sigma_m = o.telemetry_sigma_m * 1.5;
  return trial;
}

}  // namespace areomap::testing
