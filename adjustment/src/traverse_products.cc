#include "areomap/adjustment/traverse_products.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include <cpl_error.h>
#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/plot_marks.h"
#include "areomap/map/raster.h"

namespace areomap {
namespace {

std::string Fixed(double value, int decimals) {
  if (!std::isfinite(value)) return "nan";
  if (std::abs(value) < 0.5 * std::pow(10.0, -decimals)) value = 0.0;  // No "-0.000".
  char text[64];
  std::snprintf(text, sizeof(text), "%.*f", decimals, value);
  return text;
}

std::string Row(const std::vector<std::string>& cells) {
  std::string line;
  for (size_t i = 0; i < cells.size(); ++i) line += (i ? "," : "") + cells[i];
  return line + "\n";
}

bool HasTruth(const AnchoredTraverse& traverse) {
  return !traverse.sites.empty() && std::isfinite(traverse.sites.front().adjusted_error_m);
}

// Suppresses GDAL's console output while alive (libraries never print).
struct QuietGdal {
  QuietGdal() { CPLPushErrorHandler(CPLQuietErrorHandler); }
  ~QuietGdal() { CPLPopErrorHandler(); }
};

// A point at `distance` [m] from (lat, lon) [rad] along `azimuth` (clockwise from north), on
// the local sphere of radius `radius` (the ellipses are metres wide: flat is exact enough).
Eigen::Vector2d OffsetLonLatDeg(const Geographic& g, double north_m, double east_m, double radius) {
  const double lat = g.lat + north_m / radius;
  const double lon = g.lon + east_m / (radius * std::cos(g.lat));
  return {DegFromRad(lon), DegFromRad(lat)};
}

}  // namespace

void WriteTraverseSitesCsv(const std::filesystem::path& path, const AnchoredTraverse& traverse) {
  const bool truth = HasTruth(traverse);
  std::vector<std::string> header = {"site",
                                     "north_m",
                                     "east_m",
                                     "down_m",
                                     "lat_deg",
                                     "lon_deg",
                                     "h_m",
                                     "x_mbf_m",
                                     "y_mbf_m",
                                     "z_mbf_m",
                                     "sigma_north_m",
                                     "sigma_east_m",
                                     "sigma_down_m",
                                     "ellipse_major_m",
                                     "ellipse_minor_m",
                                     "ellipse_azimuth_deg",
                                     "initial_north_m",
                                     "initial_east_m",
                                     "only_priors"};
  if (truth) {
    header.insert(header.end(),
                  {"true_north_m", "true_east_m", "initial_error_m", "adjusted_error_m"});
  }
  std::string text = Row(header);
  for (const AnchoredSite& s : traverse.sites) {
    const Eigen::Vector3d& p = s.position_in_traverse;
    std::vector<std::string> row = {std::to_string(s.site),
                                    Fixed(p.x(), 4),
                                    Fixed(p.y(), 4),
                                    Fixed(p.z(), 4),
                                    Fixed(DegFromRad(s.geographic.lat), 10),
                                    Fixed(DegFromRad(s.geographic.lon), 10),
                                    Fixed(s.geographic.h, 4),
                                    Fixed(s.position_mbf.x(), 4),
                                    Fixed(s.position_mbf.y(), 4),
                                    Fixed(s.position_mbf.z(), 4),
                                    Fixed(std::sqrt(s.covariance_in_traverse(0, 0)), 4),
                                    Fixed(std::sqrt(s.covariance_in_traverse(1, 1)), 4),
                                    Fixed(s.sigma_down_m, 4),
                                    Fixed(s.ellipse.semi_major_m, 4),
                                    Fixed(s.ellipse.semi_minor_m, 4),
                                    Fixed(DegFromRad(s.ellipse.azimuth_rad), 2),
                                    Fixed(s.initial_in_traverse.x(), 4),
                                    Fixed(s.initial_in_traverse.y(), 4),
                                    s.only_priors ? "1" : "0"};
    if (truth) {
      row.insert(row.end(), {Fixed(s.truth_in_traverse.x(), 4), Fixed(s.truth_in_traverse.y(), 4),
                             Fixed(s.initial_error_m, 4), Fixed(s.adjusted_error_m, 4)});
    }
    text += Row(row);
  }
  WriteFileAtomically(path, text);
}

void WriteLegTableCsv(const std::filesystem::path& path, const AnchoredTraverse& traverse) {
  const bool truth = HasTruth(traverse);
  std::vector<std::string> header = {"site_a", "site_b", "length_m", "predicted_re_percent"};
  if (truth) header.insert(header.end(), {"telemetry_re_percent", "adjusted_re_percent"});
  std::string text = Row(header);
  for (const LegError& leg : traverse.legs) {
    std::vector<std::string> row = {std::to_string(leg.site_a), std::to_string(leg.site_b),
                                    Fixed(leg.length_m, 3), Fixed(100.0 * leg.predicted_re, 3)};
    if (truth) {
      row.insert(row.end(), {Fixed(100.0 * leg.initial_re, 3), Fixed(100.0 * leg.adjusted_re, 3)});
    }
    text += Row(row);
  }
  WriteFileAtomically(path, text);
}

namespace {

// A GeoPackage being written at a temporary path: its layers in `srs`, each failure an
// areomap::Error naming `path` (the final name) and GDAL's message.
struct GeoPackageWriter {
  std::filesystem::path path;
  std::unique_ptr<GDALDataset> dataset;
  OGRSpatialReference srs;

  OGRLayer* CreateLayer(const char* name, OGRwkbGeometryType type) {
    OGRLayer* layer = dataset->CreateLayer(name, &srs, type, nullptr);
    if (layer == nullptr) {
      throw Error(path.string() + ": cannot create layer " + name + ": " + CPLGetLastErrorMsg());
    }
    return layer;
  }
  void AddField(OGRLayer* layer, const char* name, OGRFieldType type) const {
    OGRFieldDefn field(name, type);
    if (layer->CreateField(&field) != OGRERR_NONE) {
      throw Error(path.string() + ": cannot create field " + name);
    }
  }
  void Commit(OGRLayer* layer, OGRFeature& feature) const {
    if (layer->CreateFeature(&feature) != OGRERR_NONE) {
      throw Error(path.string() + ": cannot write a feature: " + CPLGetLastErrorMsg());
    }
  }
};

// The site's 1 sigma ellipse as a closed ring of 72 points [deg lon, lat].
OGRLinearRing EllipseRing(const AnchoredSite& s, double radius) {
  OGRLinearRing ring;
  const double az = s.ellipse.azimuth_rad;
  for (int i = 0; i <= 72; ++i) {
    const double t = 2.0 * std::numbers::pi * (i % 72) / 72.0;
    const double u = s.ellipse.semi_major_m * std::cos(t);
    const double v = s.ellipse.semi_minor_m * std::sin(t);
    // Major axis along azimuth az (clockwise from north): (north, east) = (cos az, sin az).
    const double north = u * std::cos(az) - v * std::sin(az);
    const double east = u * std::sin(az) + v * std::cos(az);
    const Eigen::Vector2d lonlat = OffsetLonLatDeg(s.geographic, north, east, radius);
    ring.addPoint(lonlat.x(), lonlat.y());
  }
  return ring;
}

// The "sites" (points with their figures) and "error_ellipses" (polygons) layers.
void WriteSiteLayers(GeoPackageWriter& gpkg, const AnchoredTraverse& traverse, double radius) {
  const bool truth = HasTruth(traverse);
  OGRLayer* sites = gpkg.CreateLayer("sites", wkbPoint25D);
  for (const char* name :
       {"north_m", "east_m", "down_m", "h_m", "sigma_north_m", "sigma_east_m", "sigma_down_m",
        "ellipse_major_m", "ellipse_minor_m", "ellipse_azimuth_deg", "adjusted_error_m"}) {
    gpkg.AddField(sites, name, OFTReal);
  }
  gpkg.AddField(sites, "site", OFTInteger);
  gpkg.AddField(sites, "only_priors", OFTInteger);
  OGRLayer* ellipses = gpkg.CreateLayer("error_ellipses", wkbPolygon);
  gpkg.AddField(ellipses, "site", OFTInteger);
  for (const AnchoredSite& s : traverse.sites) {
    OGRFeature feature(sites->GetLayerDefn());
    feature.SetField("site", s.site);
    feature.SetField("north_m", s.position_in_traverse.x());
    feature.SetField("east_m", s.position_in_traverse.y());
    feature.SetField("down_m", s.position_in_traverse.z());
    feature.SetField("h_m", s.geographic.h);
    feature.SetField("sigma_north_m", std::sqrt(s.covariance_in_traverse(0, 0)));
    feature.SetField("sigma_east_m", std::sqrt(s.covariance_in_traverse(1, 1)));
    feature.SetField("sigma_down_m", s.sigma_down_m);
    feature.SetField("ellipse_major_m", s.ellipse.semi_major_m);
    feature.SetField("ellipse_minor_m", s.ellipse.semi_minor_m);
    feature.SetField("ellipse_azimuth_deg", DegFromRad(s.ellipse.azimuth_rad));
    if (truth) feature.SetField("adjusted_error_m", s.adjusted_error_m);
    feature.SetField("only_priors", s.only_priors ? 1 : 0);
    OGRPoint point(DegFromRad(s.geographic.lon), DegFromRad(s.geographic.lat), s.geographic.h);
    feature.SetGeometry(&point);
    gpkg.Commit(sites, feature);

    OGRLinearRing ring = EllipseRing(s, radius);
    OGRPolygon polygon;
    polygon.addRing(&ring);
    OGRFeature ellipse(ellipses->GetLayerDefn());
    ellipse.SetField("site", s.site);
    ellipse.SetGeometry(&polygon);
    gpkg.Commit(ellipses, ellipse);
  }
}

// A line layer `name` through every site at `position_of(site)` (in the traverse frame).
template <typename PositionOf>
void WriteTrackLayer(GeoPackageWriter& gpkg, const char* name, const AnchoredTraverse& traverse,
                     double radius, PositionOf position_of) {
  const Geographic origin =
      traverse.sites.empty() ? Geographic{} : traverse.sites.front().geographic;
  OGRLayer* layer = gpkg.CreateLayer(name, wkbLineString);
  OGRLineString line;
  for (const AnchoredSite& s : traverse.sites) {
    // Offsets from site 0's adjusted position on the local sphere (metre-scale accuracy
    // is all a drawn line needs; the sites layer holds the exact coordinates).
    const Eigen::Vector3d d = position_of(s) - traverse.sites.front().position_in_traverse;
    const Eigen::Vector2d lonlat = OffsetLonLatDeg(origin, d.x(), d.y(), radius);
    line.addPoint(lonlat.x(), lonlat.y());
  }
  OGRFeature feature(layer->GetLayerDefn());
  feature.SetGeometry(&line);
  gpkg.Commit(layer, feature);
}

}  // namespace

void WriteTraverseGeoPackage(const std::filesystem::path& path, const AnchoredTraverse& traverse,
                             const Body& body) {
  GDALAllRegister();
  const QuietGdal quiet;
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (driver == nullptr) throw Error(path.string() + ": GDAL has no GPKG driver");
  AtomicFile file(path);
  std::filesystem::remove(file.temp_path());
  {
    GeoPackageWriter gpkg;
    gpkg.path = path;
    gpkg.dataset.reset(driver->Create(file.temp_path().c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    if (!gpkg.dataset) {
      throw Error(path.string() + ": cannot create GeoPackage: " + CPLGetLastErrorMsg());
    }
    const std::string wkt = GeographicCrsWkt(body);
    gpkg.srs.importFromWkt(wkt.c_str());
    gpkg.srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    const double radius = body.RadiusAtPlanetocentricLatitude(
        traverse.sites.empty() ? 0.0 : traverse.sites.front().geographic.lat);
    WriteSiteLayers(gpkg, traverse, radius);
    WriteTrackLayer(gpkg, "adjusted", traverse, radius,
                    [](const AnchoredSite& s) { return s.position_in_traverse; });
    WriteTrackLayer(gpkg, "initial", traverse, radius,
                    [](const AnchoredSite& s) { return s.initial_in_traverse; });
    if (HasTruth(traverse)) {
      WriteTrackLayer(gpkg, "truth", traverse, radius,
                      [](const AnchoredSite& s) { return s.truth_in_traverse; });
    }
    CPLErrorReset();
    gpkg.dataset.reset();  // Closing writes the file.
    if (CPLGetLastErrorType() == CE_Failure) {
      throw Error(path.string() + ": cannot write GeoPackage: " + CPLGetLastErrorMsg());
    }
  }
  file.Commit();
}

void TraverseMapOptions::Check() const {
  RequireOption(max_size_px >= 64, "TraverseMapOptions.max_size_px", ">= 64 px");
  RequireOption(margin_m >= 0.0, "TraverseMapOptions.margin_m", ">= 0 m");
  RequireOption(ellipse_scale > 0.0, "TraverseMapOptions.ellipse_scale", "> 0");
}

namespace {

// Where traverse-frame positions fall on the orbital image. Site 0 goes through MBF and the
// image's CRS; other points are north/east offsets from it on the north-up map
// (equirectangular scale error over a kilometre: well below a pixel).
struct MapProjection {
  Eigen::Vector2d p0;  // Site 0's adjusted position [orbital px].
  Eigen::Vector3d first_in_traverse;
  double px_m = 0.0;  // Pixel size east, north [m].
  double py_m = 0.0;

  Eigen::Vector2d Pixel(const Eigen::Vector3d& in_traverse) const {
    const Eigen::Vector3d d = in_traverse - first_in_traverse;
    // North-up map: +north = -row, +east = +col (equirectangular near the centre).
    return Eigen::Vector2d(p0.x() + d.y() / px_m, p0.y() - d.x() / py_m);
  }
};

MapProjection ProjectOnImage(const AnchoredTraverse& traverse, const RasterInfo& info,
                             const std::filesystem::path& orbital_image) {
  if (!info.geotransform || info.crs_wkt.empty()) {
    throw Error(orbital_image.string() + ": the orbital image has no georeferencing");
  }
  const Crs crs = Crs::FromWkt(info.crs_wkt, orbital_image.string());
  crs.RequireMars();
  const CrsTransform transform(crs);
  const GeoTransform& geo = *info.geotransform;
  const AnchoredSite& first = traverse.sites.front();
  MapProjection projection;
  const std::optional<Eigen::Vector3d> xy = transform.FromMbf(first.position_mbf);
  projection.p0 = xy ? geo.MapToPixel(xy->x(), xy->y()) : Eigen::Vector2d::Constant(std::nan(""));
  projection.first_in_traverse = first.position_in_traverse;
  projection.px_m = std::abs(geo.c[1]);
  projection.py_m = std::abs(geo.c[5]);
  return projection;
}

// The image window holding every drawn position (telemetry, adjusted, truth) plus the margin.
PixelWindow MapWindow(const AnchoredTraverse& traverse, const MapProjection& projection,
                      const RasterInfo& info, double margin_m) {
  Eigen::Vector2d lo = projection.p0, hi = projection.p0;
  for (const AnchoredSite& s : traverse.sites) {
    for (const Eigen::Vector3d& p : {s.position_in_traverse, s.initial_in_traverse}) {
      lo = lo.cwiseMin(projection.Pixel(p));
      hi = hi.cwiseMax(projection.Pixel(p));
    }
    if (std::isfinite(s.truth_in_traverse.x())) {
      lo = lo.cwiseMin(projection.Pixel(s.truth_in_traverse));
      hi = hi.cwiseMax(projection.Pixel(s.truth_in_traverse));
    }
  }
  const Eigen::Vector2d margin(margin_m / projection.px_m, margin_m / projection.py_m);
  lo -= margin;
  hi += margin;
  PixelWindow window;
  window.col0 = std::clamp(static_cast<int>(std::floor(lo.x())), 0, info.width - 1);
  window.row0 = std::clamp(static_cast<int>(std::floor(lo.y())), 0, info.height - 1);
  window.width =
      std::clamp(static_cast<int>(std::ceil(hi.x())), window.col0 + 1, info.width) - window.col0;
  window.height =
      std::clamp(static_cast<int>(std::ceil(hi.y())), window.row0 + 1, info.height) - window.row0;
  return window;
}

// The window stretched (1-99 %) to 8 bits and resized by `scale`, as a BGR canvas.
cv::Mat MapBackground(const RasterDataset& dataset, const PixelWindow& window, double scale) {
  cv::Mat image = dataset.ReadWindowFloat(1, window);
  const std::optional<ValueRange> range = FiniteQuantileRange(image, 0.01, 0.99);
  const double low = range ? range->low : 0.0, high = range ? range->high : 1.0;
  cv::Mat gray;
  image.convertTo(gray, CV_8U, 255.0 / std::max(high - low, 1e-9),
                  -low * 255.0 / std::max(high - low, 1e-9));
  cv::Mat canvas;
  cv::resize(gray, gray, cv::Size(), scale, scale, scale < 1.0 ? cv::INTER_AREA : cv::INTER_LINEAR);
  cv::cvtColor(gray, canvas, cv::COLOR_GRAY2BGR);
  return canvas;
}

// The legend's lines top left, each in its colour over a black outline.
void DrawLegend(cv::Mat& canvas, const std::vector<std::pair<std::string, cv::Scalar>>& entries) {
  int y = 22;
  for (const auto& [text, color] : entries) {
    if (text.empty()) continue;
    cv::putText(canvas, text, cv::Point(10, y), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0),
                4, cv::LINE_AA);
    cv::putText(canvas, text, cv::Point(10, y), cv::FONT_HERSHEY_SIMPLEX, 0.6, color, 2,
                cv::LINE_AA);
    y += 24;
  }
}

}  // namespace

void WriteTraverseMap(const std::filesystem::path& path, const AnchoredTraverse& traverse,
                      const std::filesystem::path& orbital_image,
                      const TraverseMapOptions& options) {
  options.Check();
  if (traverse.sites.empty()) throw Error(path.string() + ": no sites to draw");
  const RasterDataset dataset = RasterDataset::Open(orbital_image);
  const RasterInfo& info = dataset.info();
  const MapProjection projection = ProjectOnImage(traverse, info, orbital_image);
  const PixelWindow window = MapWindow(traverse, projection, info, options.margin_m);
  const double scale =
      static_cast<double>(options.max_size_px) / std::max(window.width, window.height);
  cv::Mat canvas = MapBackground(dataset, window, scale);
  const auto to_canvas = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector2d q = projection.Pixel(p);
    return cv::Point2d((q.x() - window.col0) * scale, (q.y() - window.row0) * scale);
  };
  const auto draw_track = [&](auto position_of, const cv::Scalar& color, int thickness) {
    std::vector<cv::Point> points;
    for (const AnchoredSite& s : traverse.sites) {
      const cv::Point2d q = to_canvas(position_of(s));
      points.emplace_back(static_cast<int>(std::lround(q.x)), static_cast<int>(std::lround(q.y)));
    }
    cv::polylines(canvas, points, false, color, thickness, cv::LINE_AA);
    for (const cv::Point& p : points) {
      cv::circle(canvas, p, thickness + 1, color, cv::FILLED, cv::LINE_AA);
    }
  };
  const cv::Scalar red(40, 40, 230), green(60, 200, 60), blue(230, 120, 40);
  // Telemetry, then adjusted, then the truth on top (thinner) so that all three show where
  // they overlap.
  draw_track([](const AnchoredSite& s) { return s.initial_in_traverse; }, red, 2);
  draw_track([](const AnchoredSite& s) { return s.position_in_traverse; }, green, 3);
  if (HasTruth(traverse)) {
    draw_track([](const AnchoredSite& s) { return s.truth_in_traverse; }, blue, 1);
  }
  const double px_m = projection.px_m;
  for (const AnchoredSite& s : traverse.sites) {
    const cv::Point2d c = to_canvas(s.position_in_traverse);
    const double axis_px = options.ellipse_scale * scale / px_m;
    cv::ellipse(canvas, c,
                cv::Size2d(std::max(1.0, s.ellipse.semi_major_m * axis_px),
                           std::max(1.0, s.ellipse.semi_minor_m * axis_px)),
                DegFromRad(s.ellipse.azimuth_rad) - 90.0, 0.0, 360.0, green, 1, cv::LINE_AA);
  }
  char scale_text[96];
  std::snprintf(scale_text, sizeof(scale_text), "1 sigma ellipses x%.0f, %.2f m/px",
                options.ellipse_scale, px_m / scale);
  DrawLegend(canvas, {{"telemetry", red},
                      {"adjusted", green},
                      {HasTruth(traverse) ? "truth" : "", blue},
                      {scale_text, cv::Scalar(255, 255, 255)}});
  internal::DrawScaleBar(&canvas, cv::Point(canvas.cols - 15, canvas.rows - 15), scale / px_m);
  cv::cvtColor(canvas, canvas, cv::COLOR_BGR2RGB);  // WriteImage keeps file (RGB) order.
  WriteImage(path, canvas);
}

}  // namespace areomap
