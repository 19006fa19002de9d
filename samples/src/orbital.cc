#include "areomap/samples/orbital.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/report_progress.h"
#include "shading.h"

namespace areomap {
namespace {

// The image grid: square, north-up, whole DTM cells, rendered at `supersample` sub-pixels.
struct OrbitalGrid {
  int dtm_cells = 0;  // DTM cells along an edge.
  int size = 0;       // Image pixels along an edge.
  double left = 0.0;  // Map coordinates of the top-left corner [m].
  double top = 0.0;
  int fine = 0;       // Rendering sub-pixels along an edge.
  double cell = 0.0;  // Rendering sub-pixel size [m].
};

OrbitalGrid LayOutOrbitalGrid(const MapProjection& projection, const SceneGeoreference& georef,
                              double half_extent_m, double dtm_posting_m,
                              const OrbitalImageOptions& o) {
  // Centre the grid on the ENU origin as the map sees it (along its radial line).
  const Spherical origin_radial = SphericalFromMbf(MbfFromGeographic(georef.body, georef.origin));
  const Eigen::Vector2d center = projection.Forward({origin_radial.lat, origin_radial.lon, 0.0});
  OrbitalGrid grid;
  grid.dtm_cells = static_cast<int>(std::floor(2.0 * half_extent_m / dtm_posting_m));
  const int factor = static_cast<int>(std::lround(dtm_posting_m / o.gsd_m));
  if (std::abs(factor * o.gsd_m - dtm_posting_m) > 1e-9) {
    throw Error("orbital products: the DTM posting must be a whole multiple of the GSD");
  }
  grid.size = grid.dtm_cells * factor;
  const double extent = grid.size * o.gsd_m;
  grid.left = center.x() - extent / 2.0;
  grid.top = center.y() + extent / 2.0;
  grid.fine = grid.size * o.supersample;
  grid.cell = o.gsd_m / o.supersample;
  return grid;
}

// Map -> local ENU, exact on a coarse lattice and bilinear in between (the mapping is smooth:
// its curvature over 16 cells is below a micrometre).
constexpr int kLattice = 16;

struct MapToEnuLattice {
  cv::Mat x, y;  // ENU east and north [m] of every kLattice-th sub-pixel corner.
};

MapToEnuLattice BuildMapToEnuLattice(const MapProjection& projection,
                                     const SceneGeoreference& georef, const OrbitalGrid& grid) {
  const Rigid3d enu_from_mbf = georef.EnuFromMbf();
  const int lattice_n = grid.fine / kLattice + 2;
  MapToEnuLattice lattice{cv::Mat(lattice_n, lattice_n, CV_64F),
                          cv::Mat(lattice_n, lattice_n, CV_64F)};
  for (int r = 0; r < lattice_n; ++r) {
    for (int c = 0; c < lattice_n; ++c) {
      const Eigen::Vector2d map(grid.left + c * kLattice * grid.cell,
                                grid.top - r * kLattice * grid.cell);
      // A map-projected pixel sees its ground along the radial line of its spherical lat/lon.
      const Geographic g = projection.Inverse(map);
      const Eigen::Vector3d enu =
          enu_from_mbf * MbfOnRadialLine(georef.body, g.lat, g.lon, georef.origin.h);
      lattice.x.at<double>(r, c) = enu.x();
      lattice.y.at<double>(r, c) = enu.y();
    }
  }
  return lattice;
}

struct TerrainSamples {
  cv::Mat heights;  // CV_64F [m above the ellipsoid], one per rendering sub-pixel.
  cv::Mat albedo;   // CV_64F.
};

TerrainSamples SampleTerrain(const Scene& scene, const MapToEnuLattice& lattice, int fine) {
  TerrainSamples terrain{cv::Mat(fine, fine, CV_64F), cv::Mat(fine, fine, CV_64F)};
  tbb::parallel_for(0, fine, [&](int r) {
    for (int c = 0; c < fine; ++c) {
      const double lr = (r + 0.5) / kLattice, lc = (c + 0.5) / kLattice;
      const int r0 = static_cast<int>(lr), c0 = static_cast<int>(lc);
      const double fr = lr - r0, fc = lc - c0;
      const auto bilinear = [&](const cv::Mat& m) {
        return (1 - fr) * ((1 - fc) * m.at<double>(r0, c0) + fc * m.at<double>(r0, c0 + 1)) +
               fr * ((1 - fc) * m.at<double>(r0 + 1, c0) + fc * m.at<double>(r0 + 1, c0 + 1));
      };
      const double x = bilinear(lattice.x), y = bilinear(lattice.y);
      terrain.heights.at<double>(r, c) = scene.HeightAt(x, y);
      terrain.albedo.at<double>(r, c) = scene.AlbedoAt(x, y);
    }
  });
  return terrain;
}

// Lambertian radiance with cast shadows and ambient sky light, per rendering sub-pixel.
cv::Mat ShadeTerrain(const TerrainSamples& terrain, const OrbitalGrid& grid,
                     const OrbitalImageOptions& o) {
  const cv::Mat& heights = terrain.heights;
  const int fine = grid.fine;
  const double cell = grid.cell;
  const Eigen::Vector3d sun = internal::SunDirection(o.sun_azimuth_deg, o.sun_elevation_deg);
  const cv::Mat shadow = internal::ShadowMask(heights, cell, sun);
  cv::Mat radiance(fine, fine, CV_64F);
  tbb::parallel_for(0, fine, [&](int r) {
    for (int c = 0; c < fine; ++c) {
      const int cl = std::max(c - 1, 0), cr = std::min(c + 1, fine - 1);
      const int ru = std::max(r - 1, 0), rd = std::min(r + 1, fine - 1);
      const double dzdx =
          (heights.at<double>(r, cr) - heights.at<double>(r, cl)) / ((cr - cl) * cell);
      const double dzdy =
          (heights.at<double>(ru, c) - heights.at<double>(rd, c)) / ((rd - ru) * cell);
      const Eigen::Vector3d normal = Eigen::Vector3d(-dzdx, -dzdy, 1.0).normalized();
      const double direct = shadow.at<uchar>(r, c) ? 0.0 : std::max(0.0, normal.dot(sun));
      radiance.at<double>(r, c) =
          terrain.albedo.at<double>(r, c) * (direct + o.ambient * normal.z());
    }
  });
  return radiance;
}

// The camera: box-averaged to image pixels, MTF blur, shot and read noise, quantised DN.
cv::Mat ImageThroughOptics(const cv::Mat& radiance, int size, const OrbitalImageOptions& o) {
  cv::Mat image;
  cv::resize(radiance, image, cv::Size(size, size), 0, 0, cv::INTER_AREA);
  if (o.mtf_sigma_px > 0.0) cv::GaussianBlur(image, image, cv::Size(), o.mtf_sigma_px);
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double max_dn = std::pow(2.0, o.bits) - 1.0;
  const double gain = o.full_well_dn / 0.5;  // DN per unit radiance.
  cv::Mat dn(size, size, CV_16U);
  for (int r = 0; r < size; ++r) {
    for (int c = 0; c < size; ++c) {
      const double signal = image.at<double>(r, c) * gain;
      // Shot noise with about 8 electrons per DN, plus read noise.
      const double noisy = signal + gauss(rng) * std::sqrt(std::max(signal, 0.0) / 8.0 +
                                                           o.read_noise_dn * o.read_noise_dn);
      dn.at<uint16_t>(r, c) = static_cast<uint16_t>(std::clamp(std::round(noisy), 0.0, max_dn));
    }
  }
  return dn;
}

}  // namespace

MapProjection SceneGeoreference::Projection() const {
  return MapProjection::Equirectangular(body, origin.lat, origin.lon,
                                        EquirectangularRadius::kLocalAtCenterLatitude);
}

Rigid3d SceneGeoreference::EnuFromMbf() const { return areomap::EnuFromMbf(body, origin); }

void OrbitalImageOptions::Check() const {
  RequireOption(gsd_m > 0.0 && gsd_m <= 100.0, "OrbitalImageOptions.gsd_m", "0 < gsd <= 100 m");
  RequireOption(sun_elevation_deg > 0.0 && sun_elevation_deg < 90.0,
                "OrbitalImageOptions.sun_elevation_deg", "in (0, 90)");
  RequireOption(std::isfinite(sun_azimuth_deg), "OrbitalImageOptions.sun_azimuth_deg",
                "a finite angle");
  RequireOption(ambient >= 0.0 && ambient < 1.0, "OrbitalImageOptions.ambient", "in [0, 1)");
  RequireOption(supersample >= 1 && supersample <= 8, "OrbitalImageOptions.supersample", "1..8");
  RequireOption(mtf_sigma_px >= 0.0, "OrbitalImageOptions.mtf_sigma_px", ">= 0");
  RequireOption(read_noise_dn >= 0.0, "OrbitalImageOptions.read_noise_dn", ">= 0");
  RequireOption(bits >= 8 && bits <= 16, "OrbitalImageOptions.bits", "8..16");
  RequireOption(full_well_dn > 0.0, "OrbitalImageOptions.full_well_dn", "> 0");
}

OrbitalProducts RenderOrbitalProducts(const Scene& scene, const SceneGeoreference& georef,
                                      double half_extent_m, double dtm_posting_m,
                                      const OrbitalImageOptions& o,
                                      const ProgressCallback& progress) {
  o.Check();
  if (!(half_extent_m > 0.0) || !(dtm_posting_m >= o.gsd_m)) {
    throw Error("orbital products: half extent must be > 0 and the DTM posting >= the GSD");
  }
  const MapProjection projection = georef.Projection();
  const OrbitalGrid grid = LayOutOrbitalGrid(projection, georef, half_extent_m, dtm_posting_m, o);
  const MapToEnuLattice lattice = BuildMapToEnuLattice(projection, georef, grid);
  ReportProgress(progress, 0.05, "orbital: terrain");
  const TerrainSamples terrain = SampleTerrain(scene, lattice, grid.fine);
  ReportProgress(progress, 0.6, "orbital: shading");
  const cv::Mat radiance = ShadeTerrain(terrain, grid, o);
  ReportProgress(progress, 0.8, "orbital: optics");
  const cv::Mat dn = ImageThroughOptics(radiance, grid.size, o);
  cv::Mat dtm_fine, dtm;
  cv::resize(terrain.heights, dtm_fine, cv::Size(grid.dtm_cells, grid.dtm_cells), 0, 0,
             cv::INTER_AREA);
  dtm_fine.convertTo(dtm, CV_32F);

  OrbitalProducts out;
  const std::string wkt = projection.Wkt();
  out.image.bands = {dn};
  out.image.band_names = {"dn"};
  out.image.geotransform = GeoTransform::NorthUp(grid.left, grid.top, o.gsd_m, o.gsd_m);
  out.image.crs_wkt = wkt;
  out.dtm.bands = {dtm};
  out.dtm.band_names = {"elevation_m"};
  out.dtm.geotransform = GeoTransform::NorthUp(grid.left, grid.top, dtm_posting_m, dtm_posting_m);
  out.dtm.crs_wkt = wkt;
  out.dtm.nodata = -3.4028227e+38;
  ReportProgress(progress, 1.0, "orbital: done");
  return out;
}

}  // namespace areomap
