#include "areomap/samples/sample_terrain.h"

#include <cmath>
#include <random>
#include <sstream>

#include "areomap/map/body.h"
#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/projection.h"

namespace areomap {
namespace {

void Require(bool ok, const char* field, const char* rule, double value) {
  if (!ok) {
    std::ostringstream msg;
    msg << "SampleTerrainOptions." << field << " = " << value << " is invalid: expected " << rule;
    throw Error(msg.str());
  }
}

// Crater profile (ch. 2.1): bowl floor inside the rim, raised rim decaying outside.
double CraterHeight(double r, const SampleTerrainOptions& o) {
  const double radius = o.crater_diameter_m / 2.0;
  const double floor_depth = o.crater_depth_m - o.rim_height_m;  // Below surroundings.
  if (r <= radius) {
    const double u = r / radius;
    return -floor_depth + (o.rim_height_m + floor_depth) * u * u;  // Parabolic bowl.
  }
  const double outside = (r - radius) / (0.4 * radius);
  return o.rim_height_m * std::exp(-outside * outside * 2.0);
}

}  // namespace

void SampleTerrainOptions::Check() const {
  Require(std::abs(center_lat_deg) < 85.0, "center_lat_deg", "|lat| < 85 deg", center_lat_deg);
  Require(std::isfinite(center_lon_deg), "center_lon_deg", "a finite longitude", center_lon_deg);
  Require(size_px >= 16 && size_px <= 8192, "size_px", "16..8192", size_px);
  Require(posting_m > 0.0 && posting_m <= 1000.0, "posting_m", "0 < posting <= 1000 m", posting_m);
  Require(crater_diameter_m > 0.0, "crater_diameter_m", "> 0", crater_diameter_m);
  Require(crater_depth_m > rim_height_m, "crater_depth_m", "> rim_height_m", crater_depth_m);
  Require(rim_height_m >= 0.0, "rim_height_m", ">= 0", rim_height_m);
  Require(roughness_m >= 0.0, "roughness_m", ">= 0", roughness_m);
}

GeoRaster MakeSampleTerrain(const SampleTerrainOptions& o) {
  o.Check();
  const Body body = Body::Mars2000();
  const MapProjection projection = MapProjection::Equirectangular(
      body, RadFromDeg(o.center_lat_deg), RadFromDeg(o.center_lon_deg),
      EquirectangularRadius::kLocalAtCenterLatitude);
  const Eigen::Vector2d center_xy = projection.Forward(
      Geographic{RadFromDeg(o.center_lat_deg), RadFromDeg(o.center_lon_deg), 0.0});
  const double half = 0.5 * o.size_px * o.posting_m;

  // Fractal background: a sum of plane waves with 1/f amplitudes and seeded phases.
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> uniform(0.0, 2.0 * std::numbers::pi);
  struct Wave {
    double kx, ky, phase, amplitude;
  };
  std::vector<Wave> waves;
  const int octaves = 6;
  for (int octave = 0; octave < octaves; ++octave) {
    const double wavelength = 2.0 * half / std::pow(2.0, octave);
    for (int j = 0; j < 3; ++j) {
      const double direction = uniform(rng);
      const double k = 2.0 * std::numbers::pi / wavelength;
      waves.push_back({k * std::cos(direction), k * std::sin(direction), uniform(rng),
                       o.roughness_m / std::pow(1.8, octave)});
    }
  }

  cv::Mat dtm(o.size_px, o.size_px, CV_32F);
  for (int row = 0; row < o.size_px; ++row) {
    for (int col = 0; col < o.size_px; ++col) {
      const double x = (col + 0.5) * o.posting_m - half;  // Relative to the tile centre [m].
      const double y = half - (row + 0.5) * o.posting_m;
      double z = o.base_elevation_m + CraterHeight(std::hypot(x, y), o);
      for (const Wave& w : waves) z += w.amplitude * std::sin(w.kx * x + w.ky * y + w.phase);
      dtm.at<float>(row, col) = static_cast<float>(z);
    }
  }

  GeoRaster out;
  out.bands = {dtm};
  out.band_names = {"elevation_m"};
  out.geotransform =
      GeoTransform::NorthUp(center_xy.x() - half, center_xy.y() + half, o.posting_m, o.posting_m);
  out.crs_wkt = projection.Wkt();
  out.nodata = -3.4028227e+38;
  return out;
}

}  // namespace areomap
