// Crater catalogues on disk: CSV, JSON, GeoPackage (OGR, with the raster's Mars CRS) and an
// overlay PNG for people. All files are written atomically.
//
// Per crater: pixel coordinates (GDAL convention) and, when the raster is georeferenced, map
// coordinates of its CRS, semi-axes in metres (pixel size from the geotransform) and
// planetocentric latitude / east longitude [deg]; DTM measures when a model was made.
// Failure: unwritable destinations throw areomap::Error naming the file; WriteCratersGeoPackage
// throws when the catalogue is not georeferenced.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/crater/crater_model.h"
#include "areomap/crater/crater_score.h"
#include "areomap/crater/sun_azimuth.h"
#include "areomap/map/raster.h"

namespace areomap {

struct CatalogCrater {
  int id = 0;
  CraterDetection detection;                  // pixel frame
  std::optional<Eigen::Vector2d> map_center;  // CRS units (metres for a projected CRS)
  double semi_major_m = 0.0;                  // NaN when not georeferenced
  double semi_minor_m = 0.0;
  std::optional<double> lat_deg;  // planetocentric
  std::optional<double> lon_deg;  // east, [0, 360)
  std::optional<CraterModel> model;
};

struct CraterCatalog {
  std::vector<CatalogCrater> craters;
  std::optional<GeoTransform> geotransform;  // none for a plain image
  std::string crs_wkt;                       // empty when not georeferenced
  double pixel_size_m = 0.0;                 // ground size of a pixel; 0 when unknown

  bool IsGeoreferenced() const { return geotransform.has_value() && !crs_wkt.empty(); }
};

// Adds map coordinates, metres and lat/lon from the raster's geotransform and CRS (when it has
// both; a CRS that is not on Mars throws areomap::Error naming `info.path`).
CraterCatalog MakeCraterCatalog(const std::vector<CraterDetection>& detections,
                                const RasterInfo& info);

nlohmann::json CraterCatalogJson(const CraterCatalog& catalog);
// One bin of a crater score (crater_score.h) as JSON; NaN rates are null, an open bin edge "inf".
nlohmann::json CraterMatchStatsJson(const CraterMatchStats& stats);
// azimuth_deg (null without votes), candidates, votes, agreement, reliable.
nlohmann::json SunAzimuthEstimateJson(const SunAzimuthEstimate& estimate);
void WriteCratersCsv(const std::filesystem::path& path, const CraterCatalog& catalog);
void WriteCratersJson(const std::filesystem::path& path, const CraterCatalog& catalog);
// Layer "craters": rim polygons (72 vertices) in the raster's CRS with the CSV's attributes.
void WriteCratersGeoPackage(const std::filesystem::path& path, const CraterCatalog& catalog);
// 8-bit RGB PNG of `image` (stretched between its 1st and 99th percentiles) with the rims drawn
// (green; yellow when partial), decimated so the longer side is at most `max_side` px.
void WriteCraterOverlay(const std::filesystem::path& path, const cv::Mat& image,
                        const std::vector<CraterDetection>& detections, int max_side = 4096);

// Scoring overlay, same stretch and decimation: truth craters of at least `min_diameter`
// [px] drawn green when matched, red when missed; detections of at least `min_diameter` that
// match nothing (false alarms) in yellow, 2 px outside their rim. `score` comes from
// ScoreCraters(truth, detections, ...); all coordinates in pixels of `image`.
void WriteScoreOverlay(const std::filesystem::path& path, const cv::Mat& image,
                       const std::vector<CraterCircle>& truth,
                       const std::vector<CraterCircle>& detections, const CraterScore& score,
                       double min_diameter, int max_side = 4096);

}  // namespace areomap
