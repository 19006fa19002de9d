#include "areomap/crater/crater_output.h"

#include <cmath>
#include <iomanip>
#include <limits>
#include <numbers>
#include <sstream>

#include <gdal_priv.h>
#include <ogrsf_frmts.h>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/crater_raster.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/image_io.h"
#include "areomap/map/numbers.h"

namespace areomap {
namespace {

// Named numeric attributes of one crater, in output order (CSV columns, GeoPackage fields).
std::vector<std::pair<std::string, double>> Attributes(const CatalogCrater& c) {
  const CraterDetection& d = c.detection;
  const Ellipse& e = d.ellipse;
  std::vector<std::pair<std::string, double>> a = {
      {"x_px", e.center.x()},
      {"y_px", e.center.y()},
      {"diameter_px", d.Diameter()},
      {"semi_major_px", e.semi_major},
      {"semi_minor_px", e.semi_minor},
      {"angle_deg", e.angle * 180.0 / std::numbers::pi},
      {"eccentricity", e.Eccentricity()},
      {"x_sigma_px", d.center_x_sigma},
      {"y_sigma_px", d.center_y_sigma},
      {"semi_major_sigma_px", d.semi_major_sigma},
      {"semi_minor_sigma_px", d.semi_minor_sigma},
      {"rms_residual_px", d.rms_residual},
      {"efs", d.efs},
      {"coverage", d.coverage},
      {"signature", d.signature},
      {"confidence", d.confidence},
      {"partial", d.partial ? 1.0 : 0.0},
      {"pyramid_level", static_cast<double>(d.pyramid_level)},
      // 1: the rim was fitted as an ellipse; 0: the learned detector's circle (no rim edges)
      {"rim_fitted", d.rim_fitted ? 1.0 : 0.0},
      {"model_score", d.model_score},
      {"edge_detected", d.edge_detected ? 1.0 : 0.0},
      {"map_x", c.map_center ? c.map_center->x() : kNaN},
      {"map_y", c.map_center ? c.map_center->y() : kNaN},
      {"semi_major_m", c.semi_major_m},
      {"semi_minor_m", c.semi_minor_m},
      {"lat_deg", c.lat_deg.value_or(kNaN)},
      {"lon_deg", c.lon_deg.value_or(kNaN)},
  };
  const CraterModel m = c.model.value_or(CraterModel{});
  const double has = c.model ? 1.0 : kNaN;
  a.insert(a.end(), {{"depth_max_min_m", has * m.depth_max_min},
                     {"depth_mean_m", has * m.depth_mean},
                     {"floor_radius_m", has * m.floor_radius},
                     {"ratio1", has * m.ratio1},
                     {"ratio2", has * m.ratio2},
                     {"ratio3", has * m.ratio3}});
  return a;
}

}  // namespace

CraterCatalog MakeCraterCatalog(const std::vector<CraterDetection>& detections,
                                const RasterInfo& info) {
  CraterCatalog catalog;
  catalog.geotransform = info.geotransform;
  catalog.crs_wkt = info.crs_wkt;
  std::optional<CrsTransform> transform;
  if (catalog.IsGeoreferenced()) {
    const Crs crs = Crs::FromWkt(info.crs_wkt, info.path.string());
    crs.RequireMars();
    transform.emplace(crs);
    const auto& c = info.geotransform->c;
    const double det = std::abs(c[1] * c[5] - c[2] * c[4]);
    if (transform->description().is_projected) catalog.pixel_size_m = std::sqrt(det);
  }
  int id = 0;
  for (const CraterDetection& d : detections) {
    CatalogCrater c;
    c.id = ++id;
    c.detection = d;
    c.semi_major_m = c.semi_minor_m = kNaN;
    if (catalog.geotransform) {
      c.map_center = catalog.geotransform->PixelToMap(d.ellipse.center.x(), d.ellipse.center.y());
    }
    if (catalog.pixel_size_m > 0.0) {
      c.semi_major_m = d.ellipse.semi_major * catalog.pixel_size_m;
      c.semi_minor_m = d.ellipse.semi_minor * catalog.pixel_size_m;
    }
    if (transform && c.map_center) {
      if (const auto g = transform->ToPlanetocentric(*c.map_center)) {
        c.lat_deg = DegFromRad(g->lat);
        c.lon_deg = DegFromRad(WrapLongitude(g->lon, LongitudeDomain::kZeroTo360));
      }
    }
    catalog.craters.push_back(c);
  }
  return catalog;
}

nlohmann::json SunAzimuthEstimateJson(const SunAzimuthEstimate& e) {
  return {{"azimuth_deg",
           std::isfinite(e.azimuth_deg) ? nlohmann::json(e.azimuth_deg) : nlohmann::json()},
          {"candidates", e.candidates},
          {"votes", e.votes},
          {"agreement", e.agreement},
          {"reliable", e.reliable}};
}

nlohmann::json CraterMatchStatsJson(const CraterMatchStats& s) {
  const auto number = [](double v) {
    return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
  };
  return {{"min_diameter_px", s.min_diameter},
          {"max_diameter_px",
           std::isfinite(s.max_diameter) ? nlohmann::json(s.max_diameter) : nlohmann::json("inf")},
          {"truth", s.truth},
          {"detected", s.detected},
          {"matched_truth", s.matched_truth},
          {"matched_detected", s.matched_detected},
          {"precision", number(s.precision)},
          {"recall", number(s.recall)},
          {"f1", number(s.f1)},
          {"median_center_error_px", number(s.median_center_error)},
          {"median_diameter_error", number(s.median_diameter_error)}};
}

nlohmann::json CraterCatalogJson(const CraterCatalog& catalog) {
  nlohmann::json j;
  j["georeferenced"] = catalog.IsGeoreferenced();
  j["pixel_convention"] = "GDAL: pixel (col,row) covers [col,col+1) x [row,row+1)";
  j["craters"] = nlohmann::json::array();
  for (const CatalogCrater& c : catalog.craters) {
    nlohmann::json cj;
    cj["id"] = c.id;
    for (const auto& [name, value] : Attributes(c)) {
      cj[name] = std::isfinite(value) ? nlohmann::json(value) : nlohmann::json();
    }
    j["craters"].push_back(cj);
  }
  return j;
}

void WriteCratersCsv(const std::filesystem::path& path, const CraterCatalog& catalog) {
  std::ostringstream out;
  out << std::setprecision(10) << "id";
  for (const auto& [name, value] : Attributes(CatalogCrater{})) out << "," << name;
  out << "\n";
  for (const CatalogCrater& c : catalog.craters) {
    out << c.id;
    for (const auto& [name, value] : Attributes(c)) {
      out << ",";
      if (std::isfinite(value)) out << value;
    }
    out << "\n";
  }
  WriteFileAtomically(path, out.str());
}

void WriteCratersJson(const std::filesystem::path& path, const CraterCatalog& catalog) {
  WriteFileAtomically(path, CraterCatalogJson(catalog).dump(2) + "\n");
}

void WriteCratersGeoPackage(const std::filesystem::path& path, const CraterCatalog& catalog) {
  if (!catalog.IsGeoreferenced()) {
    throw Error(path.string() +
                ": a GeoPackage needs a georeferenced raster (geotransform and CRS)");
  }
  GDALAllRegister();
  GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GPKG");
  if (driver == nullptr) throw Error(path.string() + ": GDAL has no GPKG driver");
  AtomicFile file(path);
  {
    std::unique_ptr<GDALDataset> ds(
        driver->Create(file.temp_path().c_str(), 0, 0, 0, GDT_Unknown, nullptr));
    if (!ds) throw Error(path.string() + ": cannot create GeoPackage");
    OGRSpatialReference srs;
    srs.SetAxisMappingStrategy(OAMS_TRADITIONAL_GIS_ORDER);
    if (srs.importFromWkt(catalog.crs_wkt.c_str()) != OGRERR_NONE) {
      throw Error(path.string() + ": the raster's CRS cannot be written");
    }
    OGRLayer* layer = ds->CreateLayer("craters", &srs, wkbPolygon, nullptr);
    if (layer == nullptr) throw Error(path.string() + ": cannot create layer 'craters'");
    OGRFieldDefn id_field("id", OFTInteger);
    layer->CreateField(&id_field);
    for (const auto& [name, value] : Attributes(CatalogCrater{})) {
      OGRFieldDefn field(name.c_str(), OFTReal);
      layer->CreateField(&field);
    }
    if (layer->StartTransaction() != OGRERR_NONE) {
      throw Error(path.string() + ": cannot start a transaction");
    }
    for (const CatalogCrater& c : catalog.craters) {
      OGRFeature feature(layer->GetLayerDefn());
      feature.SetField("id", c.id);
      for (const auto& [name, value] : Attributes(c)) {
        if (std::isfinite(value)) feature.SetField(name.c_str(), value);
      }
      OGRLinearRing ring;
      const Ellipse& e = c.detection.ellipse;
      constexpr int kVertices = 72;
      for (int k = 0; k <= kVertices; ++k) {
        const Eigen::Vector2d p = e.PointAt(2.0 * std::numbers::pi * (k % kVertices) / kVertices);
        const Eigen::Vector2d m = catalog.geotransform->PixelToMap(p.x(), p.y());
        ring.addPoint(m.x(), m.y());
      }
      OGRPolygon polygon;
      polygon.addRing(&ring);
      feature.SetGeometry(&polygon);
      if (layer->CreateFeature(&feature) != OGRERR_NONE) {
        throw Error(path.string() + ": cannot write crater " + std::to_string(c.id));
      }
    }
    if (layer->CommitTransaction() != OGRERR_NONE) {
      throw Error(path.string() + ": cannot commit the craters");
    }
  }
  file.Commit();
}

namespace {

// `image` stretched between its 1st and 99th percentiles into 8-bit RGB, decimated by a power
// of two (*factor) so the longer side is at most `max_side`.
cv::Mat StretchedRgb(const cv::Mat& image, int max_side, int* factor) {
  cv::Mat f;
  image.convertTo(f, CV_32F);
  *factor = DecimationFactor(f.cols, f.rows, max_side);
  if (*factor > 1) {
    cv::resize(f, f, cv::Size(f.cols / *factor, f.rows / *factor), 0, 0, cv::INTER_AREA);
  }
  const std::optional<ValueRange> range = FiniteQuantileRange(f, 0.01, 0.99, 2);
  double lo = range ? range->low : 0.0, hi = range ? range->high : 1.0;
  if (!(hi > lo)) hi = lo + 1.0;
  cv::Mat gray;
  f.convertTo(gray, CV_8U, 255.0 / (hi - lo), -lo * 255.0 / (hi - lo));
  cv::Mat rgb;
  cv::cvtColor(gray, rgb, cv::COLOR_GRAY2RGB);
  return rgb;
}

constexpr int kDrawShift = 4;  // sub-pixel drawing

// GDAL pixel coordinates [px of the full image] -> fixed-point drawing coordinates.
cv::Point DrawPoint(const Eigen::Vector2d& p, int factor) {
  const double s = (1 << kDrawShift) / static_cast<double>(factor);
  return {static_cast<int>(std::lround((p.x() - 0.5 * factor) * s)),
          static_cast<int>(std::lround((p.y() - 0.5 * factor) * s))};
}

int DrawLength(double length, int factor) {
  return static_cast<int>(std::lround(length * (1 << kDrawShift) / static_cast<double>(factor)));
}

}  // namespace

void WriteCraterOverlay(const std::filesystem::path& path, const cv::Mat& image,
                        const std::vector<CraterDetection>& detections, int max_side) {
  int factor = 1;
  cv::Mat rgb = StretchedRgb(image, max_side, &factor);
  for (const CraterDetection& d : detections) {
    const Ellipse& e = d.ellipse;
    const cv::Size axes(DrawLength(e.semi_major, factor), DrawLength(e.semi_minor, factor));
    const cv::Scalar color = d.partial ? cv::Scalar(255, 220, 0) : cv::Scalar(0, 255, 0);
    cv::ellipse(rgb, DrawPoint(e.center, factor), axes, e.angle * 180.0 / std::numbers::pi, 0, 360,
                color, 1, cv::LINE_AA, kDrawShift);
  }
  WriteImage(path, rgb);
}

void WriteScoreOverlay(const std::filesystem::path& path, const cv::Mat& image,
                       const std::vector<CraterCircle>& truth,
                       const std::vector<CraterCircle>& detections, const CraterScore& score,
                       double min_diameter, int max_side) {
  int factor = 1;
  cv::Mat rgb = StretchedRgb(image, max_side, &factor);
  std::vector<char> truth_matched(truth.size(), 0), detection_matched(detections.size(), 0);
  for (const auto& [t, d] : score.matches) {
    if (t >= 0 && static_cast<size_t>(t) < truth.size()) truth_matched[static_cast<size_t>(t)] = 1;
    if (d >= 0 && static_cast<size_t>(d) < detections.size()) {
      detection_matched[static_cast<size_t>(d)] = 1;
    }
  }
  const auto circle = [&](const CraterCircle& c, double radius_pad, const cv::Scalar& color) {
    cv::circle(rgb, DrawPoint(c.center, factor), DrawLength(0.5 * c.diameter + radius_pad, factor),
               color, 1, cv::LINE_AA, kDrawShift);
  };
  for (size_t i = 0; i < truth.size(); ++i) {
    if (truth[i].diameter < min_diameter) continue;
    circle(truth[i], 0.0, truth_matched[i] ? cv::Scalar(0, 255, 0) : cv::Scalar(255, 0, 0));
  }
  for (size_t i = 0; i < detections.size(); ++i) {
    if (detections[i].diameter < min_diameter || detection_matched[i]) continue;
    circle(detections[i], 2.0 * factor, cv::Scalar(255, 220, 0));
  }
  WriteImage(path, rgb);
}

}  // namespace areomap
