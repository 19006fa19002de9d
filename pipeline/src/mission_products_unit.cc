// The whole-traverse products of a mission run (products/): one DTM and one orthomosaic of every
// site with the bundle-adjusted site poses, and how well they sit on the orbital DTM and image
// compared with the same DTM made from the telemetry poses.
//
// Memory stays bounded by a site or two: each site's cloud is read, gridded on its window of the
// common traverse grid (with both poses) and dropped; the windows are merged afterwards
// (MergeGriddedLayers), as MakeDtm does for clouds held together.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <cpl_string.h>
#include <gdal.h>
#include <gdal_utils.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/mosaic.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_image.h"
#include "mission_units.h"

namespace areomap::mission_run {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();

// Ground a site's products can reach around its origin on the map [m] (orthophoto.h's window:
// map scale differs from 1 by < 2 %).
double SiteReach(const MissionRunOptions& options) {
  return 1.02 * std::max(options.stereo.max_range_m, options.ortho.max_range_m) + 2.0;
}

Eigen::Vector2d SiteOnMap(const MissionRunContext& run, const SiteGeoreference& georef) {
  return run.map.MapFromMbf(georef.mbf_from_site.translation).head<2>();
}

// `raster` (e.g. an orbital DTM or image) sampled bilinearly at the cell centres of `grid`
// (a grid on the run's map); NaN off the raster or next to its nodata.
cv::Mat ResampleOntoGrid(const OrbitalImage& raster, const GridSpec& grid,
                         const std::string& grid_wkt) {
  const GridMapping mapping(PixelGrid(grid.Transform(), grid_wkt, "traverse grid"),
                            PixelGrid(raster.geotransform(), raster.crs_wkt(), raster.name()));
  cv::Mat map_xy(grid.height, grid.width, CV_32FC2);
  Eigen::Vector2d min = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d max = -min;
  for (int row = 0; row < grid.height; ++row) {
    for (int col = 0; col < grid.width; ++col) {
      const Eigen::Vector2d p = mapping.Apply({col + 0.5, row + 0.5});
      map_xy.at<cv::Vec2f>(row, col) =
          cv::Vec2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
      if (p.allFinite()) {
        min = min.cwiseMin(p);
        max = max.cwiseMax(p);
      }
    }
  }
  cv::Mat sampled(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  if (!min.allFinite()) return sampled;
  PixelWindow window{static_cast<int>(std::floor(min.x())) - 1,
                     static_cast<int>(std::floor(min.y())) - 1,
                     static_cast<int>(std::ceil(max.x() - min.x())) + 3,
                     static_cast<int>(std::ceil(max.y() - min.y())) + 3};
  const cv::Mat pixels = raster.ReadWindow(window);
  if (pixels.empty()) return sampled;
  // GDAL pixel coordinates (centres at +0.5) -> OpenCV's (centres at integers) in the window.
  const cv::Vec2f shift(static_cast<float>(window.col0) + 0.5f,
                        static_cast<float>(window.row0) + 0.5f);
  map_xy.forEach<cv::Vec2f>([&](cv::Vec2f& p, const int*) { p -= shift; });
  cv::remap(pixels, sampled, map_xy, cv::noArray(), cv::INTER_LINEAR, cv::BORDER_CONSTANT,
            cv::Scalar(kNaNf));
  return sampled;
}

// Differences rover DTM - orbital DTM over the cells both know [m].
TraverseDifference DifferenceStats(const cv::Mat& rover, const cv::Mat& orbital) {
  double sum = 0.0, sum_sq = 0.0;
  std::vector<double> absolute;
  for (int row = 0; row < rover.rows; ++row) {
    for (int col = 0; col < rover.cols; ++col) {
      const double d = rover.at<float>(row, col) - orbital.at<float>(row, col);
      if (!std::isfinite(d)) continue;
      sum += d;
      sum_sq += d * d;
      absolute.push_back(std::abs(d));
    }
  }
  if (absolute.empty()) return {};
  const double n = static_cast<double>(absolute.size());
  const double mean = sum / n;
  auto middle = absolute.begin() + static_cast<std::ptrdiff_t>(absolute.size() / 2);
  std::nth_element(absolute.begin(), middle, absolute.end());
  return {static_cast<int64_t>(absolute.size()), mean, std::sqrt(sum_sq / n),
          std::sqrt(std::max(0.0, sum_sq / n - mean * mean)), *middle};
}

// Pearson correlation of two images over the cells where both are finite.
TraverseCorrelation Correlation(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat valid = (a == a) & (b == b);  // NaN != NaN.
  const int n = cv::countNonZero(valid);
  if (n < 2) return {n, std::nullopt};
  cv::Mat a64, b64;
  a.convertTo(a64, CV_64F);
  b.convertTo(b64, CV_64F);
  cv::Scalar mean_a, std_a, mean_b, std_b;
  cv::meanStdDev(a64, mean_a, std_a, valid);
  cv::meanStdDev(b64, mean_b, std_b, valid);
  cv::Mat product = (a64 - mean_a[0]).mul(b64 - mean_b[0]);
  const double covariance = cv::mean(product, valid)[0];
  return {n, covariance / (std_a[0] * std_b[0])};
}

// An 8-bit picture of `values` stretched between its 1st and 99th percentiles (NaN black),
// shrunk so that its longer side is at most `max_side` px.
cv::Mat Thumbnail(const cv::Mat& values, int max_side) {
  cv::Mat picture(values.size(), CV_8U, cv::Scalar(0));
  if (const std::optional<ValueRange> range = FiniteQuantileRange(values, 0.01, 0.99)) {
    const double lo = range->low, hi = std::max(range->high, lo + 1e-6);
    const cv::Mat nodata = NanMask(values);
    cv::Mat clean = values.clone();
    clean.setTo(lo, nodata);
    clean.convertTo(picture, CV_8U, 254.0 / (hi - lo), 1.0 - 254.0 * lo / (hi - lo));
    picture.setTo(0, nodata);
  }
  const double scale =
      std::min(1.0, static_cast<double>(max_side) / std::max(values.cols, values.rows));
  if (scale < 1.0) cv::resize(picture, picture, cv::Size(), scale, scale, cv::INTER_AREA);
  return picture;
}

// A shaded relief of a DTM GeoTIFF (GDAL's hillshade: sun from the north-west, 45 degrees
// high, slopes in the DTM's own metres), 0 where unknown, shrunk to at most `max_side` px.
cv::Mat ShadedRelief(const fs::path& dtm_tif, int max_side) {
  GDALDatasetH source = GDALOpen(dtm_tif.string().c_str(), GA_ReadOnly);
  if (source == nullptr) throw Error(dtm_tif.string() + ": cannot open the DTM for its relief");
  CPLStringList arguments;
  for (const char* argument : {"-of", "MEM", "-compute_edges", "-b", "1"}) {
    arguments.AddString(argument);
  }
  GDALDEMProcessingOptions* options = GDALDEMProcessingOptionsNew(arguments.List(), nullptr);
  int usage_error = 0;
  GDALDatasetH shaded = GDALDEMProcessing("", source, "hillshade", nullptr, options, &usage_error);
  GDALDEMProcessingOptionsFree(options);
  GDALClose(source);
  if (shaded == nullptr) throw Error(dtm_tif.string() + ": GDAL could not shade the DTM");
  cv::Mat relief(GDALGetRasterYSize(shaded), GDALGetRasterXSize(shaded), CV_8U);
  const CPLErr status =
      GDALRasterIO(GDALGetRasterBand(shaded, 1), GF_Read, 0, 0, relief.cols, relief.rows,
                   relief.data, relief.cols, relief.rows, GDT_Byte, 0, 0);
  GDALClose(shaded);
  if (status != CE_None) throw Error(dtm_tif.string() + ": GDAL could not read the relief");
  const double scale =
      std::min(1.0, static_cast<double>(max_side) / std::max(relief.cols, relief.rows));
  if (scale < 1.0) cv::resize(relief, relief, cv::Size(), scale, scale, cv::INTER_AREA);
  return relief;
}

struct SiteLayers {
  GriddedLayers adjusted;
  GriddedLayers telemetry;
};

// One site's cloud gridded on its windows of `grid` with both poses.
SiteLayers GridSite(const MissionRunContext& run, size_t index, const SiteGeoreference& adjusted,
                    const SiteGeoreference& telemetry, const GridSpec& grid,
                    const DtmOptions& dtm_options) {
  const PointCloud cloud =
      ReadPointCloudPly(SiteDir(run, run.mission->sites[index].site) / "points.ply");
  const Eigen::Vector2d reach = Eigen::Vector2d::Constant(SiteReach(*run.options));
  SiteLayers layers;
  for (const auto& [georef, out] :
       {std::pair{&adjusted, &layers.adjusted}, std::pair{&telemetry, &layers.telemetry}}) {
    const Eigen::Vector2d centre = SiteOnMap(run, *georef);
    DtmOptions options = dtm_options;
    options.grid = grid.Window(centre - reach, centre + reach);
    if (!options.grid) {
      throw Error("traverse DTM: site " + std::to_string(run.mission->sites[index].site) +
                  " lies outside the traverse grid");
    }
    *out = MakeDtm({SiteCloud{&cloud, *georef}}, run.map, options).layers;
  }
  return layers;
}

std::vector<std::array<double, 7>> PoseRecords(const std::vector<Rigid3d>& poses) {
  std::vector<std::array<double, 7>> out;
  for (const Rigid3d& pose : poses) {
    const Eigen::Quaterniond& q = pose.rotation;
    out.push_back({pose.translation.x(), pose.translation.y(), pose.translation.z(), q.w(), q.x(),
                   q.y(), q.z()});
  }
  return out;
}

}  // namespace

bool SamePoses(const std::vector<std::array<double, 7>>& recorded,
               const std::vector<Rigid3d>& poses) {
  const std::vector<std::array<double, 7>> now = PoseRecords(poses);
  if (recorded.size() != now.size()) return false;
  for (size_t i = 0; i < now.size(); ++i) {
    for (size_t k = 0; k < 7; ++k) {
      // 0.1 mm, 1e-4 in a quaternion component (~2e-4 rad, 3 mm at 15 m): far below the
      // products' posting, above solver round-off. (A NaN recorded: not the same.)
      if (!(std::abs(recorded[i][k] - now[i][k]) <= 1e-4)) return false;
    }
  }
  return true;
}

namespace {

// Every site placed twice, with the adjusted and with the telemetry poses, and the traverse grid
// covering both.
struct TraversePlacement {
  std::vector<SiteGeoreference> adjusted, telemetry;
  DtmOptions dtm_options;  // The run's, at the traverse posting.
  GridSpec grid;
};

TraversePlacement PlaceSites(const MissionRunContext& run,
                             const std::vector<Rigid3d>& traverse_from_site) {
  const MissionManifest& mission = *run.mission;
  const MissionRunOptions& options = *run.options;
  TraversePlacement out;
  Eigen::Vector2d min = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d max = -min;
  const double reach = SiteReach(options);
  for (size_t i = 0; i < mission.sites.size(); ++i) {
    out.adjusted.push_back(
        SiteGeoreference::InMission(mission.body, mission.origin, traverse_from_site[i]));
    out.telemetry.push_back(SiteGeoreference::InMission(
        mission.body, mission.origin, TelemetryTraverseFromSite(mission.telemetry[i])));
    for (const SiteGeoreference* g : {&out.adjusted.back(), &out.telemetry.back()}) {
      const Eigen::Vector2d centre = SiteOnMap(run, *g);
      min = min.cwiseMin(centre - Eigen::Vector2d::Constant(reach));
      max = max.cwiseMax(centre + Eigen::Vector2d::Constant(reach));
    }
  }
  out.dtm_options = options.dtm;
  out.dtm_options.posting_m = options.traverse_posting_m;
  out.dtm_options.grid.reset();
  out.grid = GridSpec::Covering(min, max, out.dtm_options.posting_m);
  return out;
}

struct TraverseDtms {
  Dtm adjusted, telemetry;
};

// Every site's points gridded with both poses and merged.
TraverseDtms MakeTraverseDtms(const MissionRunContext& run, const TraversePlacement& placement) {
  const size_t site_count = run.mission->sites.size();
  std::vector<GriddedLayers> adjusted_layers(site_count), telemetry_layers(site_count);
  tbb::parallel_for(size_t{0}, site_count, [&](size_t i) {
    SiteLayers layers = GridSite(run, i, placement.adjusted[i], placement.telemetry[i],
                                 placement.grid, placement.dtm_options);
    adjusted_layers[i] = std::move(layers.adjusted);
    telemetry_layers[i] = std::move(layers.telemetry);
  });
  return {Dtm{MergeGriddedLayers(adjusted_layers, placement.grid), run.map.Wkt()},
          Dtm{MergeGriddedLayers(telemetry_layers, placement.grid), run.map.Wkt()}};
}

struct TraverseMosaics {
  Orthophoto adjusted, telemetry;
};

// The orthomosaic with both poses (the telemetry one only to be compared with the orbital
// image, not written). Calls `report` between the orthophotos and the mosaics.
TraverseMosaics MakeTraverseMosaics(const MissionRunContext& run,
                                    const TraversePlacement& placement, const TraverseDtms& dtms,
                                    const std::function<void()>& report) {
  const MissionManifest& mission = *run.mission;
  const MissionRunOptions& options = *run.options;
  const size_t site_count = mission.sites.size();
  std::vector<Orthophoto> orthophotos(site_count), telemetry_orthophotos(site_count);
  tbb::parallel_for(size_t{0}, site_count, [&](size_t i) {
    const int first_id = static_cast<int>(i * 1000);  // Unique image ids across the mosaic.
    const std::vector<OrthoSourceImage> images = SiteOrthoImages(mission.sites[i], first_id);
    orthophotos[i] =
        MakeOrthophoto(dtms.adjusted, placement.adjusted[i], run.map, images, options.ortho);
    telemetry_orthophotos[i] =
        MakeOrthophoto(dtms.telemetry, placement.telemetry[i], run.map, images, options.ortho);
  });
  report();
  return {MakeOrthomosaic(orthophotos, dtms.adjusted.layers.grid, dtms.adjusted.crs_wkt,
                          options.mosaic),
          MakeOrthomosaic(telemetry_orthophotos, placement.grid, dtms.adjusted.crs_wkt,
                          options.mosaic)};
}

// The products against the mission's orbital DTM and image (each when the mission has one),
// added to `summary`.
void CompareWithOrbital(const MissionRunContext& run, const GridSpec& grid,
                        const TraverseDtms& dtms, const TraverseMosaics& mosaics,
                        ProductsUnitResult& summary) {
  const MissionManifest& mission = *run.mission;
  if (const MissionOrbitalProduct* orbital_dtm = mission.FirstOrbital("dtm")) {
    const cv::Mat reference =
        ResampleOntoGrid(OrbitalImage::Open(orbital_dtm->path), grid, run.map.Wkt());
    summary.orbital_dtm = orbital_dtm->path.filename().string();
    summary.dtm_minus_orbital_adjusted = DifferenceStats(dtms.adjusted.layers.elevation, reference);
    summary.dtm_minus_orbital_telemetry =
        DifferenceStats(dtms.telemetry.layers.elevation, reference);
  }
  if (const MissionOrbitalProduct* image = mission.FirstOrbital("image")) {
    const cv::Mat reference =
        ResampleOntoGrid(OrbitalImage::Open(image->path), grid, run.map.Wkt());
    summary.orbital_image = image->path.filename().string();
    summary.ortho_vs_orbital_adjusted = Correlation(mosaics.adjusted.image, reference);
    summary.ortho_vs_orbital_telemetry = Correlation(mosaics.telemetry.image, reference);
  }
}

}  // namespace

ProductsUnitResult MakeTraverseProducts(const MissionRunContext& run,
                                        const std::vector<Rigid3d>& traverse_from_site,
                                        const ProgressCallback& progress) {
  const size_t site_count = run.mission->sites.size();
  if (traverse_from_site.size() != site_count) {
    throw Error("traverse products: " + std::to_string(traverse_from_site.size()) +
                " adjusted poses for " + std::to_string(site_count) + " sites");
  }
  const fs::path dir = run.out_dir / "products";
  fs::create_directories(dir);
  const auto report = [&](double f, std::string_view stage) {
    if (progress && !progress(f, stage)) throw Error("cancelled during the traverse products");
  };
  const TraversePlacement placement = PlaceSites(run, traverse_from_site);
  const GridSpec& grid = placement.grid;

  ProductsUnitResult summary;
  auto clock = std::chrono::steady_clock::now();
  const auto lap = [&](const char* part) {
    summary.seconds[part] =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - clock).count();
    clock = std::chrono::steady_clock::now();
  };

  report(0.0, "traverse DTM");
  const TraverseDtms dtms = MakeTraverseDtms(run, placement);
  WriteDtm(dir / "traverse_dtm.tif", dtms.adjusted);
  WriteImage(dir / "traverse_dtm.png", ShadedRelief(dir / "traverse_dtm.tif", 1000));
  lap("dtm");

  report(0.4, "traverse orthomosaic");
  const TraverseMosaics mosaics =
      MakeTraverseMosaics(run, placement, dtms, [&] { report(0.8, "traverse orthomosaic"); });
  WriteOrthophoto(dir / "traverse_ortho.tif", mosaics.adjusted);
  WriteImage(dir / "traverse_ortho.png", Thumbnail(mosaics.adjusted.image, 1000));
  lap("orthomosaic");

  report(0.9, "comparison with the orbital data");
  const double cell_area = grid.posting * grid.posting;
  summary.posting_m = grid.posting;
  summary.width = grid.width;
  summary.height = grid.height;
  summary.dtm_known_area_m2 = dtms.adjusted.layers.known_cells * cell_area;
  summary.ortho_valid_area_m2 = mosaics.adjusted.valid_cells * cell_area;
  summary.files = {"traverse_dtm.tif", "traverse_dtm.png", "traverse_ortho.tif",
                   "traverse_ortho.png"};
  summary.poses = PoseRecords(traverse_from_site);
  CompareWithOrbital(run, grid, dtms, mosaics, summary);
  lap("comparison");
  report(1.0, "traverse products");
  return summary;
}

}  // namespace areomap::mission_run
