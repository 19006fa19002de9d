// Products of an anchored traverse: CSV tables (sites, legs), a GeoPackage (sites with their
// 1 sigma ellipses, adjusted / initial / true traverse lines) in the body's geographic CRS, and
// a traverse map PNG over an orbital image (like the dissertation's Fig. 5.7).
//
// Units at this I/O boundary: degrees for angles, metres for lengths. Every file is written
// atomically; failures throw areomap::Error naming the file.
#pragma once

#include <filesystem>

#include "areomap/adjustment/traverse_anchoring.h"
#include "areomap/map/body.h"

namespace areomap {

// sites.csv: site, north_m, east_m, down_m (traverse frame), lat_deg, lon_deg (planetocentric,
// east), h_m, x_mbf_m, y_mbf_m, z_mbf_m, sigma_north_m, sigma_east_m, sigma_down_m,
// ellipse_major_m, ellipse_minor_m, ellipse_azimuth_deg, initial_north_m, initial_east_m,
// only_priors, and with truth true_north_m, true_east_m, initial_error_m, adjusted_error_m.
void WriteTraverseSitesCsv(const std::filesystem::path& path, const AnchoredTraverse& traverse);

// legs.csv (Tables 4.6 / 5.2): site_a, site_b, length_m, predicted_re_percent, and with truth
// telemetry_re_percent, adjusted_re_percent.
void WriteLegTableCsv(const std::filesystem::path& path, const AnchoredTraverse& traverse);

// GeoPackage with layers "sites" (points), "error_ellipses" (1 sigma polygons), "adjusted",
// "initial" and, with truth, "truth" (line strings), in GeographicCrsWkt(body).
void WriteTraverseGeoPackage(const std::filesystem::path& path, const AnchoredTraverse& traverse,
                             const Body& body);

struct TraverseMapOptions {
  int max_size_px = 1600;       // Longest side of the PNG [px] (resampled).
  double margin_m = 40.0;       // Ground shown around the traverse [m].
  double ellipse_scale = 10.0;  // 1 sigma ellipses drawn this many times larger.
  void Check() const;
};

// Draws the initial (telemetry, red), adjusted (green, with 1 sigma ellipses) and true (blue,
// when known) traverses over the georeferenced orbital image `orbital_image` (any GDAL raster
// with a Mars CRS, north up, map units metres, e.g. an equirectangular HiRISE RDR) and writes
// a PNG. Site 0 is placed through MBF and the image's CRS, the rest by their offsets from it.
void WriteTraverseMap(const std::filesystem::path& path, const AnchoredTraverse& traverse,
                      const std::filesystem::path& orbital_image,
                      const TraverseMapOptions& options = {});

}  // namespace areomap
