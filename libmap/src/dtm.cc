#include "areomap/map/dtm.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include <tbb/parallel_for.h>

#include "areomap/map/error.h"
#include "areomap/map/report_progress.h"

namespace areomap {
namespace {}  // namespace

void DtmOptions::Check() const {
  RequireOption(posting_m > 0.0 && posting_m <= 100.0, "DtmOptions.posting_m", "in (0, 100] m");
  if (grid) grid->Check();
  gridding.Check();
}

GeoRaster Dtm::ToGeoRaster() const {
  GeoRaster raster;
  cv::Mat count;
  layers.count.convertTo(count, CV_32F);
  raster.bands = {layers.elevation, count, layers.stddev, layers.sigma};
  raster.band_names = {"elevation", "count", "stddev", "sigma"};
  raster.geotransform = layers.grid.Transform();
  raster.crs_wkt = crs_wkt;
  raster.nodata = std::numeric_limits<double>::quiet_NaN();
  return raster;
}

std::vector<GridPoint> PointsOnMap(const PointCloud& cloud, const SiteGeoreference& site,
                                   const MapFrame& map) {
  CheckPointCloud(cloud, cloud.frame);
  // The map axes turn by microradians over a site: one Jacobian serves all its points.
  const Eigen::Matrix3d map_from_site_axes =
      map.JacobianAt(site.mbf_from_site * cloud.camera_center) *
      site.mbf_from_site.RotationMatrix();
  std::vector<GridPoint> points(cloud.points.size());
  tbb::parallel_for(size_t{0}, cloud.points.size(), [&](size_t i) {
    const StereoPoint& p = cloud.points[i];
    points[i].xyz = map.MapFromMbf(site.mbf_from_site * p.position);
    points[i].covariance = map_from_site_axes * p.covariance * map_from_site_axes.transpose();
  });
  for (const GridPoint& p : points) {
    if (!p.xyz.allFinite()) throw Error(cloud.frame + ": a point falls outside the map's CRS");
  }
  return points;
}

GriddedLayers MergeGriddedLayers(const std::vector<GriddedLayers>& sites, const GridSpec& grid) {
  grid.Check();
  constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
  GriddedLayers out;
  out.grid = grid;
  out.elevation = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  out.sigma = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  out.stddev = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  out.count = cv::Mat(grid.height, grid.width, CV_32S, cv::Scalar(0));
  cv::Mat weight_sum(grid.height, grid.width, CV_64F, cv::Scalar(0.0));
  cv::Mat weighted(grid.height, grid.width, CV_64F, cv::Scalar(0.0));
  cv::Mat best_weight(grid.height, grid.width, CV_64F, cv::Scalar(0.0));
  for (const GriddedLayers& site : sites) {
    const Eigen::Vector2i offset = site.grid.OffsetIn(grid);
    const int col0 = offset.x(), row0 = offset.y();
    tbb::parallel_for(0, site.grid.height, [&](int r) {
      for (int c = 0; c < site.grid.width; ++c) {
        const int row = row0 + r, col = col0 + c;
        out.count.at<int32_t>(row, col) += site.count.at<int32_t>(r, c);
        const float z = site.elevation.at<float>(r, c);
        if (!std::isfinite(z)) continue;
        const float sigma = site.sigma.at<float>(r, c);
        // Without a usable sigma every site weighs the same.
        const double w = std::isfinite(sigma) ? 1.0 / std::max(double{sigma} * sigma, 1e-12) : 1.0;
        weight_sum.at<double>(row, col) += w;
        weighted.at<double>(row, col) += w * z;
        if (w > best_weight.at<double>(row, col)) {
          best_weight.at<double>(row, col) = w;
          out.stddev.at<float>(row, col) = site.stddev.at<float>(r, c);
        }
      }
    });
  }
  int known = 0;
  for (int row = 0; row < grid.height; ++row) {
    for (int col = 0; col < grid.width; ++col) {
      const double w = weight_sum.at<double>(row, col);
      if (w <= 0.0) continue;
      ++known;
      out.elevation.at<float>(row, col) = static_cast<float>(weighted.at<double>(row, col) / w);
      out.sigma.at<float>(row, col) = static_cast<float>(1.0 / std::sqrt(w));
    }
  }
  out.known_cells = known;
  return out;
}

Dtm MakeDtm(const std::vector<SiteCloud>& sites, const MapFrame& map, const DtmOptions& options,
            const ProgressCallback& progress) {
  options.Check();
  if (sites.empty()) throw Error("DTM: no point clouds given");
  std::vector<std::vector<GridPoint>> points;
  Eigen::Vector2d min = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d max = -min;
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> bounds;
  for (const SiteCloud& site : sites) {
    if (site.cloud == nullptr) throw Error("DTM: a site has no point cloud");
    points.push_back(PointsOnMap(*site.cloud, site.georef, map));
    Eigen::Vector2d site_min = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d site_max = -site_min;
    for (const GridPoint& p : points.back()) {
      site_min = site_min.cwiseMin(p.xyz.head<2>());
      site_max = site_max.cwiseMax(p.xyz.head<2>());
    }
    bounds.emplace_back(site_min, site_max);
    min = min.cwiseMin(site_min);
    max = max.cwiseMax(site_max);
  }
  ReportProgress(progress, 0.1, "DTM: points on the map");
  const GridSpec grid =
      options.grid ? *options.grid : GridSpec::Covering(min, max, options.posting_m);
  std::vector<GriddedLayers> layers;
  for (size_t s = 0; s < sites.size(); ++s) {
    const std::optional<GridSpec> window = grid.Window(bounds[s].first, bounds[s].second);
    if (!window) continue;
    const double from = 0.1 + 0.8 * static_cast<double>(s) / static_cast<double>(sites.size());
    const double to = 0.1 + 0.8 * static_cast<double>(s + 1) / static_cast<double>(sites.size());
    const ProgressCallback stage = [&](double f, std::string_view name) {
      return progress ? progress(from + (to - from) * f, name) : true;
    };
    GriddingOptions site_options = options.gridding;
    site_options.viewpoint =
        map.MapFromMbf(sites[s].georef.mbf_from_site * sites[s].cloud->camera_center).head<2>();
    layers.push_back(GridPoints(points[s], *window, site_options, stage));
    points[s] = {};  // Free as we go.
  }
  Dtm dtm;
  dtm.crs_wkt = map.Wkt();
  dtm.layers = layers.size() == 1 && layers.front().grid.width == grid.width &&
                       layers.front().grid.height == grid.height
                   ? std::move(layers.front())
                   : MergeGriddedLayers(layers, grid);
  ReportProgress(progress, 1.0, "DTM: done");
  return dtm;
}

void WriteDtm(const std::filesystem::path& path, const Dtm& dtm) {
  WriteGeoTiff(path, dtm.ToGeoRaster());
}

GridSpec GridOfRaster(const RasterInfo& info, const std::string& source) {
  if (!info.geotransform) throw Error(source + ": not georeferenced (no geotransform)");
  const std::array<double, 6>& c = info.geotransform->c;
  if (c[2] != 0.0 || c[4] != 0.0 || !(c[1] > 0.0) || std::abs(c[1] + c[5]) > 1e-9 * c[1]) {
    throw Error(source + ": expected a north-up raster with square cells");
  }
  GridSpec grid;
  grid.x_left = c[0];
  grid.y_top = c[3];
  grid.posting = c[1];
  grid.width = info.width;
  grid.height = info.height;
  grid.Check();
  return grid;
}

namespace {

// The DTM's bands over `cells` (pixels of the raster) on `grid` (their grid).
Dtm ReadDtmCells(const RasterDataset& dataset, const PixelWindow& cells, const GridSpec& grid) {
  const RasterInfo& info = dataset.info();
  Dtm dtm;
  dtm.crs_wkt = info.crs_wkt;
  GriddedLayers& l = dtm.layers;
  l.grid = grid;
  l.elevation = dataset.ReadWindowFloat(1, cells);
  const bool layered = info.band_count >= 4;
  l.count = cv::Mat(l.grid.height, l.grid.width, CV_32S, cv::Scalar(0));
  if (layered) dataset.ReadWindowFloat(2, cells).convertTo(l.count, CV_32S);
  l.stddev = layered ? dataset.ReadWindowFloat(3, cells)
                     : cv::Mat(l.grid.height, l.grid.width, CV_32F,
                               cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  l.sigma = layered ? dataset.ReadWindowFloat(4, cells)
                    : cv::Mat(l.grid.height, l.grid.width, CV_32F,
                              cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (int row = 0; row < l.grid.height; ++row) {
    for (int col = 0; col < l.grid.width; ++col) {
      l.known_cells += std::isfinite(l.elevation.at<float>(row, col)) ? 1 : 0;
    }
  }
  return dtm;
}

RasterDataset OpenDtm(const std::filesystem::path& path) {
  RasterDataset dataset = RasterDataset::Open(path);
  if (dataset.info().crs_wkt.empty()) throw Error(path.string() + ": the DTM has no CRS");
  return dataset;
}

}  // namespace

Dtm ReadDtm(const std::filesystem::path& path) {
  const RasterDataset dataset = OpenDtm(path);
  return ReadDtmCells(dataset, dataset.FullWindow(), GridOfRaster(dataset.info(), path.string()));
}

Dtm ReadDtm(const std::filesystem::path& path, const GridSpec& window) {
  const RasterDataset dataset = OpenDtm(path);
  const GridSpec whole = GridOfRaster(dataset.info(), path.string());
  Eigen::Vector2i offset;
  try {
    offset = window.OffsetIn(whole);
  } catch (const Error&) {
    throw Error(path.string() + ": the window asked for is not a window of the DTM's grid");
  }
  return ReadDtmCells(dataset, PixelWindow{offset.x(), offset.y(), window.width, window.height},
                      window);
}

}  // namespace areomap
