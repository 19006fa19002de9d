#include "areomap/map/orthophoto.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include <tbb/parallel_for.h>

#include "areomap/map/error.h"
#include "areomap/map/raster_window.h"
#include "areomap/map/report_progress.h"

namespace areomap {
namespace {

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// A cell's ground point and upward unit normal in the site frame (NaN where the DTM is unknown).
struct GroundCells {
  int width = 0;
  int height = 0;
  std::vector<Eigen::Vector3d> point;
  std::vector<Eigen::Vector3d> normal;
  std::vector<float> sigma;  // DTM 1 sigma [m] (0 where unknown).
  const Eigen::Vector3d& At(int col, int row) const {
    return point[static_cast<size_t>(row) * width + col];
  }
};

GroundCells GroundInSite(const GriddedLayers& dtm, const GridSpec& window,
                         const SiteGeoreference& site, const MapFrame& map,
                         double normal_baseline_m) {
  const Eigen::Vector2i offset = window.OffsetIn(dtm.grid);
  const Rigid3d site_from_mbf = site.mbf_from_site.Inverse();
  GroundCells cells;
  cells.width = window.width;
  cells.height = window.height;
  const size_t n = static_cast<size_t>(window.width) * window.height;
  const Eigen::Vector3d nan3 = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  cells.point.assign(n, nan3);
  cells.normal.assign(n, nan3);
  cells.sigma.assign(n, 0.0f);
  tbb::parallel_for(0, window.height, [&](int row) {
    for (int col = 0; col < window.width; ++col) {
      const float z = dtm.elevation.at<float>(row + offset.y(), col + offset.x());
      if (!std::isfinite(z)) continue;
      const Eigen::Vector2d xy = window.CellCenter(col, row);
      const float sigma = dtm.sigma.at<float>(row + offset.y(), col + offset.x());
      cells.sigma[static_cast<size_t>(row) * window.width + col] =
          std::isfinite(sigma) ? sigma : 0.0f;
      cells.point[static_cast<size_t>(row) * window.width + col] =
          site_from_mbf * map.MbfFromMap({xy.x(), xy.y(), z});
    }
  });
  // Normals from the neighbours `reach` cells away (central differences over the baseline, so
  // the DTM's own noise does not tilt them; one-sided at gaps); site z is down.
  const int reach =
      std::max(1, static_cast<int>(std::lround(0.5 * normal_baseline_m / window.posting)));
  tbb::parallel_for(0, window.height, [&](int row) {
    for (int col = 0; col < window.width; ++col) {
      const Eigen::Vector3d& p = cells.At(col, row);
      if (!p.allFinite()) continue;
      const auto pick = [&](int c, int r) -> const Eigen::Vector3d& {
        if (c < 0 || r < 0 || c >= window.width || r >= window.height) return p;
        const Eigen::Vector3d& q = cells.At(c, r);
        return q.allFinite() ? q : p;
      };
      const Eigen::Vector3d east = pick(col + reach, row) - pick(col - reach, row);
      const Eigen::Vector3d north = pick(col, row - reach) - pick(col, row + reach);
      Eigen::Vector3d normal = east.cross(north);
      if (!(normal.norm() > 0.0)) normal = Eigen::Vector3d(0.0, 0.0, -1.0);
      normal.normalize();
      if (normal.z() > 0.0) normal = -normal;  // Up is -z in the site frame.
      cells.normal[static_cast<size_t>(row) * window.width + col] = normal;
    }
  });
  return cells;
}

// Range from the camera of every cell within reach, and the depth buffer of the cell quads.
cv::Mat DepthBuffer(const GroundCells& cells, const CahvorModel& camera, int image_width,
                    int image_height, double max_range) {
  std::vector<Eigen::Vector3f> projected(cells.point.size(),
                                         Eigen::Vector3f::Constant(kNaNf));  // (x, y, range)
  for (size_t i = 0; i < cells.point.size(); ++i) {
    const Eigen::Vector3d& p = cells.point[i];
    if (!p.allFinite()) continue;
    const double range = (p - camera.c).norm();
    if (range > max_range) continue;
    const std::optional<Eigen::Vector2d> pixel = camera.Project(p);
    if (!pixel) continue;
    projected[i] = Eigen::Vector3f(static_cast<float>(pixel->x()), static_cast<float>(pixel->y()),
                                   static_cast<float>(range));
  }
  cv::Mat depth(image_height, image_width, CV_32F, cv::Scalar(kInf));
  const auto draw = [&](const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                        const Eigen::Vector3f& c) {
    const float area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (!(std::abs(area) > 1e-12f)) return;
    // Pixel bounds, clamped before the cast (points near the camera plane project far away).
    const auto bound = [](float v, int hi) {
      return static_cast<int>(std::clamp(v, -1.0f, static_cast<float>(hi) + 1.0f));
    };
    const int x0 = std::max(0, bound(std::ceil(std::min({a.x(), b.x(), c.x()})), image_width));
    const int x1 =
        std::min(image_width - 1, bound(std::floor(std::max({a.x(), b.x(), c.x()})), image_width));
    const int y0 = std::max(0, bound(std::ceil(std::min({a.y(), b.y(), c.y()})), image_height));
    const int y1 = std::min(image_height - 1,
                            bound(std::floor(std::max({a.y(), b.y(), c.y()})), image_height));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const float px = static_cast<float>(x), py = static_cast<float>(y);
        const float wb = ((px - a.x()) * (c.y() - a.y()) - (py - a.y()) * (c.x() - a.x())) / area;
        const float wc = ((b.x() - a.x()) * (py - a.y()) - (b.y() - a.y()) * (px - a.x())) / area;
        const float wa = 1.0f - wb - wc;
        constexpr float kEdge = -1e-4f;  // Closes cracks between neighbouring triangles.
        if (wa < kEdge || wb < kEdge || wc < kEdge) continue;
        float& d = depth.at<float>(y, x);
        d = std::min(d, wa * a.z() + wb * b.z() + wc * c.z());
      }
    }
  };
  for (int row = 0; row + 1 < cells.height; ++row) {
    for (int col = 0; col + 1 < cells.width; ++col) {
      const size_t i00 = static_cast<size_t>(row) * cells.width + col;
      const Eigen::Vector3f& p00 = projected[i00];
      const Eigen::Vector3f& p10 = projected[i00 + 1];
      const Eigen::Vector3f& p01 = projected[i00 + cells.width];
      const Eigen::Vector3f& p11 = projected[i00 + cells.width + 1];
      const bool ok00 = p00.allFinite(), ok10 = p10.allFinite();
      const bool ok01 = p01.allFinite(), ok11 = p11.allFinite();
      if (ok00 && ok10 && ok11) draw(p00, p10, p11);
      if (ok00 && ok11 && ok01) draw(p00, p11, p01);
      if (!ok11 && ok00 && ok10 && ok01) draw(p00, p10, p01);
      if (!ok00 && ok10 && ok11 && ok01) draw(p10, p11, p01);
    }
  }
  return depth;
}

float Bilinear(const cv::Mat& image, double x, double y) {
  const int x0 = std::clamp(static_cast<int>(std::floor(x)), 0, image.cols - 1);
  const int y0 = std::clamp(static_cast<int>(std::floor(y)), 0, image.rows - 1);
  const int x1 = std::min(x0 + 1, image.cols - 1), y1 = std::min(y0 + 1, image.rows - 1);
  const double fx = std::clamp(x - x0, 0.0, 1.0), fy = std::clamp(y - y0, 0.0, 1.0);
  return static_cast<float>(
      (1 - fy) * ((1 - fx) * image.at<float>(y0, x0) + fx * image.at<float>(y0, x1)) +
      fy * ((1 - fx) * image.at<float>(y1, x0) + fx * image.at<float>(y1, x1)));
}

// The source images as CV_32F; throws naming an image that is empty or not single-channel.
std::vector<cv::Mat> FloatImages(const std::vector<OrthoSourceImage>& images) {
  std::vector<cv::Mat> float_images;
  for (const OrthoSourceImage& source : images) {
    const std::string name = "orthophoto: image " + std::to_string(source.id);
    if (source.image.empty()) throw Error(name + " is empty");
    if (source.image.channels() != 1) throw Error(name + ": expected a single-channel image");
    cv::Mat f;
    source.image.convertTo(f, CV_32F);
    float_images.push_back(f);
  }
  return float_images;
}

// An orthophoto on `grid` with no valid cell yet.
Orthophoto EmptyOrthophoto(const GridSpec& grid, const std::string& crs_wkt) {
  Orthophoto ortho;
  ortho.crs_wkt = crs_wkt;
  ortho.grid = grid;
  const int w = grid.width, h = grid.height;
  ortho.image = cv::Mat(h, w, CV_32F, cv::Scalar(kNaNf));
  ortho.resolution = cv::Mat(h, w, CV_32F, cv::Scalar(kNaNf));
  ortho.valid = cv::Mat(h, w, CV_8U, cv::Scalar(0));
  ortho.source_id = cv::Mat(h, w, CV_32S, cv::Scalar(-1));
  return ortho;
}

// Each image's depth buffer of the ground cells, in parallel.
std::vector<cv::Mat> DepthBuffers(const GroundCells& cells,
                                  const std::vector<OrthoSourceImage>& images,
                                  const std::vector<cv::Mat>& float_images,
                                  const OrthoOptions& options) {
  std::vector<cv::Mat> depth(images.size());
  tbb::parallel_for(size_t{0}, images.size(), [&](size_t i) {
    depth[i] = DepthBuffer(cells, images[i].camera_in_site, float_images[i].cols,
                           float_images[i].rows, options.max_range_m);
  });
  return depth;
}

// The source images with what sampling needs of each: the CV_32F pixels and the depth buffer.
struct OrthoSources {
  const std::vector<OrthoSourceImage>& images;
  const std::vector<cv::Mat>& float_images;
  const std::vector<cv::Mat>& depth;
};

struct BestView {
  double gsd = 0.0;       // Ground sample distance of the image at the cell [m].
  size_t image = 0;       // Index into the source images.
  Eigen::Vector2d pixel;  // Where the image sees the cell.
};

// The image that sees ground cell `k` (finite) at the finest resolution: within range, at most
// the maximum incidence, inside the image and not hidden by nearer ground; nullopt if none.
std::optional<BestView> BestViewOfCell(const GroundCells& cells, size_t k,
                                       const OrthoSources& sources, const OrthoOptions& options,
                                       double min_cos) {
  const Eigen::Vector3d& p = cells.point[k];
  double best_gsd = std::numeric_limits<double>::infinity();
  int best = -1;
  Eigen::Vector2d best_pixel;
  for (size_t i = 0; i < sources.images.size(); ++i) {
    const CahvorModel& camera = sources.images[i].camera_in_site;
    const Eigen::Vector3d to_camera = camera.c - p;
    const double range = to_camera.norm();
    if (range > options.max_range_m) continue;
    const double cos_incidence = cells.normal[k].dot(to_camera) / range;
    if (cos_incidence < min_cos) continue;
    const std::optional<Eigen::Vector2d> pixel = camera.Project(p);
    const cv::Mat& image = sources.float_images[i];
    if (!pixel || pixel->x() < 0.0 || pixel->y() < 0.0 || pixel->x() > image.cols - 1.0 ||
        pixel->y() > image.rows - 1.0) {
      continue;
    }
    const float buffer = sources.depth[i].at<float>(static_cast<int>(std::lround(pixel->y())),
                                                    static_cast<int>(std::lround(pixel->x())));
    // The surface's height error moves where a grazing ray meets it by sigma / cos(i).
    const double tolerance = options.depth_tolerance_m + options.depth_tolerance_relative * range +
                             options.depth_tolerance_sigmas * cells.sigma[k] / cos_incidence;
    if (range > buffer + tolerance) {
      continue;  // Something nearer hides the cell.
    }
    const Eigen::Vector2d focal = camera.FocalLengths();
    const double gsd = range / (0.5 * (focal.x() + focal.y()) * cos_incidence);
    if (gsd < best_gsd) {
      best_gsd = gsd;
      best = static_cast<int>(i);
      best_pixel = *pixel;
    }
  }
  if (best < 0) return std::nullopt;
  return BestView{best_gsd, static_cast<size_t>(best), best_pixel};
}

}  // namespace

void OrthoOptions::Check() const {
  RequireOption(max_range_m > 0.0, "OrthoOptions.max_range_m", "a positive range [m]");
  RequireOption(max_incidence_deg > 0.0 && max_incidence_deg < 90.0,
                "OrthoOptions.max_incidence_deg", "in (0, 90) degrees");
  RequireOption(normal_baseline_m > 0.0, "OrthoOptions.normal_baseline_m", "a positive length [m]");
  RequireOption(depth_tolerance_sigmas >= 0.0, "OrthoOptions.depth_tolerance_sigmas", ">= 0");
  RequireOption(depth_tolerance_m >= 0.0, "OrthoOptions.depth_tolerance_m", ">= 0 m");
  RequireOption(depth_tolerance_relative >= 0.0 && depth_tolerance_relative < 1.0,
                "OrthoOptions.depth_tolerance_relative", "in [0, 1)");
}

namespace {
// The bands of an orthophoto GeoTIFF, in order, as written and as expected when read.
const std::array<const char*, 4> kOrthophotoBands = {"image", "valid", "resolution_m", "source_id"};
}  // namespace

GeoRaster Orthophoto::ToGeoRaster() const {
  GeoRaster raster;
  cv::Mat valid_f, id_f;
  valid.convertTo(valid_f, CV_32F);
  source_id.convertTo(id_f, CV_32F);
  raster.bands = {image, valid_f, resolution, id_f};
  raster.band_names.assign(kOrthophotoBands.begin(), kOrthophotoBands.end());
  raster.geotransform = grid.Transform();
  raster.crs_wkt = crs_wkt;
  raster.nodata = std::numeric_limits<double>::quiet_NaN();
  return raster;
}

std::optional<GridSpec> OrthophotoWindow(const GridSpec& dtm_grid, const SiteGeoreference& site,
                                         const MapFrame& map,
                                         const std::vector<OrthoSourceImage>& images,
                                         const OrthoOptions& options) {
  // The cameras, not the site origin: a MER rover works tens of metres from its site's origin.
  // Map scale differs from 1 by < 2 %.
  Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d high = -low;
  for (const OrthoSourceImage& source : images) {
    const Eigen::Vector2d camera =
        map.MapFromMbf(site.mbf_from_site * source.camera_in_site.c).head<2>();
    if (!camera.allFinite()) {
      throw Error("orthophoto: image " + std::to_string(source.id) +
                  ": the camera is outside the map's CRS domain");
    }
    low = low.cwiseMin(camera);
    high = high.cwiseMax(camera);
  }
  if (images.empty()) return std::nullopt;
  const Eigen::Vector2d reach = Eigen::Vector2d::Constant(1.02 * options.max_range_m + 2.0);
  return dtm_grid.Window(low - reach, high + reach);
}

Orthophoto MakeOrthophoto(const Dtm& dtm, const SiteGeoreference& site, const MapFrame& map,
                          const std::vector<OrthoSourceImage>& images, const OrthoOptions& options,
                          const ProgressCallback& progress) {
  options.Check();
  if (images.empty()) throw Error("orthophoto: no images given");
  const std::vector<cv::Mat> float_images = FloatImages(images);
  const std::optional<GridSpec> window =
      OrthophotoWindow(dtm.layers.grid, site, map, images, options);
  if (!window) throw Error("orthophoto: the DTM does not reach the cameras");
  Orthophoto ortho = EmptyOrthophoto(*window, dtm.crs_wkt);
  ReportProgress(progress, 0.0, "orthophoto: ground");
  const GroundCells cells = GroundInSite(dtm.layers, *window, site, map, options.normal_baseline_m);
  ReportProgress(progress, 0.2, "orthophoto: depth buffers");
  const std::vector<cv::Mat> depth = DepthBuffers(cells, images, float_images, options);
  ReportProgress(progress, 0.6, "orthophoto: sampling");
  const OrthoSources sources{images, float_images, depth};
  const double min_cos = std::cos(options.max_incidence_deg * 3.14159265358979323846 / 180.0);
  tbb::parallel_for(0, window->height, [&](int row) {
    for (int col = 0; col < window->width; ++col) {
      const size_t k = static_cast<size_t>(row) * window->width + col;
      if (!cells.point[k].allFinite()) continue;
      const std::optional<BestView> best = BestViewOfCell(cells, k, sources, options, min_cos);
      if (!best) continue;
      ortho.image.at<float>(row, col) =
          Bilinear(float_images[best->image], best->pixel.x(), best->pixel.y());
      ortho.resolution.at<float>(row, col) = static_cast<float>(best->gsd);
      ortho.valid.at<uint8_t>(row, col) = 1;
      ortho.source_id.at<int32_t>(row, col) = images[best->image].id;
    }
  });
  ortho.valid_cells = cv::countNonZero(ortho.valid);
  ReportProgress(progress, 1.0, "orthophoto: done");
  return ortho;
}

void WriteOrthophoto(const std::filesystem::path& path, const Orthophoto& ortho) {
  WriteGeoTiff(path, ortho.ToGeoRaster());
}

namespace {

// Opens an orthophoto written by WriteOrthophoto, its layout checked (ReadOrthophoto's errors).
RasterDataset OpenOrthophoto(const std::filesystem::path& path) {
  RasterDataset dataset = RasterDataset::Open(path);
  const RasterInfo& info = dataset.info();
  if (info.band_count != static_cast<int>(kOrthophotoBands.size())) {
    throw Error(path.string() +
                ": expected an areomap orthophoto (4 bands: image, valid, resolution_m, "
                "source_id), found " +
                std::to_string(info.band_count) + " band(s)");
  }
  // The bands as areomap names them: another 4-band product (a DTM: elevation, count, ...)
  // must not be blended as an image. Files without band descriptions are taken as they are.
  for (size_t b = 0; b < kOrthophotoBands.size(); ++b) {
    const std::string& found = info.band_descriptions[b];
    if (!found.empty() && found != kOrthophotoBands[b]) {
      throw Error(path.string() + ": expected an areomap orthophoto (bands image, valid, " +
                  "resolution_m, source_id); band " + std::to_string(b + 1) + " is '" + found +
                  "'");
    }
  }
  return dataset;
}

}  // namespace

std::optional<GridSpec> OrthophotoValidWindow(const std::filesystem::path& path) {
  const RasterDataset dataset = OpenOrthophoto(path);
  const GridSpec grid = GridOfRaster(dataset.info(), path.string());
  const std::optional<PixelWindow> painted = ValidPixelWindow(dataset, 2, ValidCells::kPositive);
  if (!painted) return std::nullopt;
  GridSpec window = grid;
  window.x_left = grid.x_left + painted->col0 * grid.posting;
  window.y_top = grid.y_top - painted->row0 * grid.posting;
  window.width = painted->width;
  window.height = painted->height;
  return window;
}

namespace {

// The orthophoto's cells `cells` of an opened file, on `window` (their grid).
Orthophoto ReadOrthophotoCells(const RasterDataset& dataset, const PixelWindow& cells,
                               const GridSpec& window) {
  const RasterInfo& info = dataset.info();
  Orthophoto ortho;
  ortho.grid = window;
  ortho.crs_wkt = info.crs_wkt;
  ortho.image = dataset.ReadWindowFloat(1, cells);
  cv::Mat valid = dataset.ReadWindowFloat(2, cells), id = dataset.ReadWindowFloat(4, cells);
  valid.convertTo(ortho.valid, CV_8U);
  id.convertTo(ortho.source_id, CV_32S);
  ortho.resolution = dataset.ReadWindowFloat(3, cells);
  ortho.valid_cells = cv::countNonZero(ortho.valid);
  return ortho;
}

}  // namespace

Orthophoto ReadOrthophoto(const std::filesystem::path& path) {
  const RasterDataset dataset = OpenOrthophoto(path);
  return ReadOrthophotoCells(dataset, dataset.FullWindow(),
                             GridOfRaster(dataset.info(), path.string()));
}

Orthophoto ReadOrthophoto(const std::filesystem::path& path, const GridSpec& window) {
  const RasterDataset dataset = OpenOrthophoto(path);
  Eigen::Vector2i offset;
  try {
    offset = window.OffsetIn(GridOfRaster(dataset.info(), path.string()));
  } catch (const Error&) {
    throw Error(path.string() + ": the window asked for is not a window of the orthophoto's grid");
  }
  return ReadOrthophotoCells(
      dataset, PixelWindow{offset.x(), offset.y(), window.width, window.height}, window);
}

}  // namespace areomap
