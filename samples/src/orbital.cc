#include "areomap/samples/orbital.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "shading.h"

namespace areomap {
namespace {

void Report(const ProgressCallback& progress, double fraction, std::string_view stage) {
  if (progress && !progress(fraction, stage)) throw Error("orbital rendering cancelled");
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
  const Rigid3d enu_from_mbf = georef.EnuFromMbf();
  // Centre the grid on the ENU origin as the map sees it (along its radial line).
  const Spherical origin_radial = SphericalFromMbf(MbfFromGeographic(georef.body, georef.origin));
  const Eigen::Vector2d center = projection.Forward({origin_radial.lat, origin_radial.lon, 0.0});
  // The image grid: square, north-up, whole DTM cells.
  const int dtm_cells = static_cast<int>(std::floor(2.0 * half_extent_m / dtm_posting_m));
  const int factor = static_cast<int>(std::lround(dtm_posting_m / o.gsd_m));
  if (std::abs(factor * o.gsd_m - dtm_posting_m) > 1e-9) {
    throw Error("orbital products: the DTM posting must be a whole multiple of the GSD");
  }
  const int size = dtm_cells * factor;
  const double extent = size * o.gsd_m;
  const double left = center.x() - extent / 2.0, top = center.y() + extent / 2.0;
  const int ss = o.supersample;
  const int fine = size * ss;
  const double cell = o.gsd_m / ss;

  // Map -> local ENU, exact on a coarse lattice and bilinear in between (the mapping is smooth:
  // its curvature over 16 cells is below a micrometre).
  constexpr int kLattice = 16;
  const int lattice_n = fine / kLattice + 2;
  cv::Mat lattice_x(lattice_n, lattice_n, CV_64F), lattice_y(lattice_n, lattice_n, CV_64F);
  for (int r = 0; r < lattice_n; ++r) {
    for (int c = 0; c < lattice_n; ++c) {
      const Eigen::Vector2d map(left + c * kLattice * cell, top - r * kLattice * cell);
      // A map-projected pixel sees its ground along the radial line of its spherical lat/lon.
      const Geographic g = projection.Inverse(map);
      const Eigen::Vector3d enu =
          enu_from_mbf * MbfOnRadialLine(georef.body, g.lat, g.lon, georef.origin.h);
      lattice_x.at<double>(r, c) = enu.x();
      lattice_y.at<double>(r, c) = enu.y();
    }
  }
  Report(progress, 0.05, "orbital: terrain");
  cv::Mat heights(fine, fine, CV_64F), albedo(fine, fine, CV_64F);
  tbb::parallel_for(0, fine, [&](int r) {
    for (int c = 0; c < fine; ++c) {
      const double lr = (r + 0.5) / kLattice, lc = (c + 0.5) / kLattice;
      const int r0 = static_cast<int>(lr), c0 = static_cast<int>(lc);
      const double fr = lr - r0, fc = lc - c0;
      const auto bilinear = [&](const cv::Mat& m) {
        return (1 - fr) * ((1 - fc) * m.at<double>(r0, c0) + fc * m.at<double>(r0, c0 + 1)) +
               fr * ((1 - fc) * m.at<double>(r0 + 1, c0) + fc * m.at<double>(r0 + 1, c0 + 1));
      };
      const double x = bilinear(lattice_x), y = bilinear(lattice_y);
      heights.at<double>(r, c) = scene.HeightAt(x, y);
      albedo.at<double>(r, c) = scene.AlbedoAt(x, y);
    }
  });
  Report(progress, 0.6, "orbital: shading");
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
      radiance.at<double>(r, c) = albedo.at<double>(r, c) * (direct + o.ambient * normal.z());
    }
  });
  Report(progress, 0.8, "orbital: optics");
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
  cv::Mat dtm_fine, dtm;
  cv::resize(heights, dtm_fine, cv::Size(dtm_cells, dtm_cells), 0, 0, cv::INTER_AREA);
  dtm_fine.convertTo(dtm, CV_32F);

  OrbitalProducts out;
  const std::string wkt = projection.Wkt();
  out.image.bands = {dn};
  out.image.band_names = {"dn"};
  out.image.geotransform = GeoTransform::NorthUp(left, top, o.gsd_m, o.gsd_m);
  out.image.crs_wkt = wkt;
  out.dtm.bands = {dtm};
  out.dtm.band_names = {"elevation_m"};
  out.dtm.geotransform = GeoTransform::NorthUp(left, top, dtm_posting_m, dtm_posting_m);
  out.dtm.crs_wkt = wkt;
  out.dtm.nodata = -3.4028227e+38;
  Report(progress, 1.0, "orbital: done");
  return out;
}

}  // namespace areomap
