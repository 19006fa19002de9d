#include "areomap/registration/orbital_report.h"

#include <cmath>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <sstream>

#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"
#include "areomap/map/image_io.h"
#include "areomap/registration/orbital_grid.h"

namespace areomap {
namespace {

nlohmann::json MatrixJson(const Eigen::Matrix3d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2)});
  return rows;
}

// Finite values as JSON numbers, others as null (JSON has no inf/NaN).
nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

// The point's corrected position, its height the DTM's where `dtm` defines one there, else the
// prior's `prior_h` (with no_dtm_sigma_m).
void SetPosition(const Geographic& corrected, double prior_h,
                 const std::optional<OrbitalImage>& dtm, const std::optional<PixelGrid>& dtm_grid,
                 const ControlPointOptions& options, OrbitalControlPoint& p) {
  p.geographic = corrected;
  p.geographic.h = prior_h;
  p.sigma_up_m = options.no_dtm_sigma_m;
  if (dtm_grid) {
    const Eigen::Vector2d q = dtm_grid->GeographicToPixel(corrected);
    const double h = dtm->SampleBilinear(q.x(), q.y());
    if (std::isfinite(h)) {
      p.geographic.h = h;
      p.sigma_up_m = options.dtm_sigma_m;
      p.height_from_dtm = true;
    }
  }
}

// Each point's MBF covariance. The shift is one error shared by every point (see the header): n
// times its covariance each. So is a low correlation's share of the rotation's error, which
// moves each point across its offset from the pivot (OrbitalMatch::TurnLeverPx; `turn_levers_en`
// per point [m/rad]).
void ShareMatchCovariance(const OrbitalMatch& match,
                          const std::vector<Eigen::Vector2d>& turn_levers_en, const Body& body,
                          std::vector<OrbitalControlPoint>& out) {
  const double shared_by = static_cast<double>(out.size());
  const double turn_variance = std::pow(match.low_correlation_rotation_sigma_rad, 2);
  for (size_t i = 0; i < out.size(); ++i) {
    OrbitalControlPoint& p = out[i];
    const Eigen::Vector2d& lever_en = turn_levers_en[i];
    Eigen::Matrix3d cov_enu = Eigen::Matrix3d::Zero();
    cov_enu.topLeftCorner<2, 2>() = shared_by * (match.template_shift_covariance_en_m2 +
                                                 turn_variance * lever_en * lever_en.transpose());
    cov_enu(2, 2) = p.sigma_up_m * p.sigma_up_m;
    const Eigen::Matrix3d mbf_from_enu =
        EnuFromMbf(body, p.geographic).RotationMatrix().transpose();
    p.point.covariance_mbf = mbf_from_enu * cov_enu * mbf_from_enu.transpose();
  }
}

}  // namespace

void ControlPointOptions::Check() const {
  RequireOption(spacing_m > 0.0, "ControlPointOptions.spacing_m", "> 0 m");
  RequireOption(dtm_sigma_m > 0.0, "ControlPointOptions.dtm_sigma_m", "> 0 m");
  RequireOption(no_dtm_sigma_m > 0.0, "ControlPointOptions.no_dtm_sigma_m", "> 0 m");
  RequireOption(site_sigma_m > 0.0, "ControlPointOptions.site_sigma_m", "> 0 m");
}

std::vector<OrbitalControlPoint> MakeControlPoints(const OrbitalMatch& match,
                                                   const OrthoImage& ortho,
                                                   const OrbitalImage& orbital,
                                                   const OrbitalPrior& prior,
                                                   const std::optional<OrbitalImage>& dtm,
                                                   const ControlPointOptions& options) {
  options.Check();
  std::vector<OrbitalControlPoint> out;
  if (!match.matched || match.templ.empty()) return out;
  const PixelGrid orbital_grid(orbital.geotransform(), orbital.crs_wkt(), orbital.name());
  std::optional<PixelGrid> dtm_grid;
  if (dtm) dtm_grid.emplace(dtm->geotransform(), dtm->crs_wkt(), dtm->name());
  // Map-projected pixels see the ground along the radial line of their planetocentric
  // latitude and longitude (ISIS, HiRISE RDR); heights are above the IAU 2000 ellipsoid.
  const Body body = Body::Mars2000();
  std::optional<Rigid3d> site_from_mbf;
  if (ortho.site && ortho.site_origin) site_from_mbf = SiteFromMbf(body, *ortho.site_origin);
  const std::string stem = std::filesystem::path(orbital.name()).stem().string();
  const int step = std::max(1, static_cast<int>(std::lround(options.spacing_m / match.gsd_m)));
  const OrbitalTemplate& t = match.templ;
  std::vector<Eigen::Vector2d> turn_levers_en;  // Per point: OrbitalMatch::TurnLeverPx [m/rad].
  for (int r = step / 2; r < t.image.rows; r += step) {
    for (int c = step / 2; c < t.image.cols; c += step) {
      if (!t.mask.at<uchar>(r, c)) continue;
      OrbitalControlPoint p;
      p.ortho_px = Eigen::Vector2d(t.ortho_x.at<float>(r, c), t.ortho_y.at<float>(r, c));
      const Eigen::Vector2d template_px(c + 0.5, r + 0.5);
      p.orbital_px = match.TemplateToOrbital(template_px);
      const auto corrected = orbital_grid.PixelToGeographic(p.orbital_px);
      const auto telemetry =
          orbital_grid.PixelToGeographic(template_px + Eigen::Vector2d(t.col0, t.row0));
      if (!corrected || !telemetry || !p.ortho_px.allFinite()) continue;
      SetPosition(*corrected, prior.position.h, dtm, dtm_grid, options, p);
      p.sigma_east_m = std::sqrt(match.template_shift_covariance_en_m2(0, 0));
      p.sigma_north_m = std::sqrt(match.template_shift_covariance_en_m2(1, 1));
      p.false_match_probability = match.false_match_probability;
      ControlPoint& cp = p.point;
      cp.id = stem + "-cp" + std::to_string(out.size());
      cp.source = std::filesystem::path(orbital.name()).filename().string() + " ncc";
      cp.position_mbf = MbfOnRadialLine(body, p.geographic.lat, p.geographic.lon, p.geographic.h);
      if (site_from_mbf) {
        cp.site = *ortho.site;
        cp.position_in_site =
            *site_from_mbf * MbfOnRadialLine(body, telemetry->lat, telemetry->lon, p.geographic.h);
        cp.covariance_in_site =
            options.site_sigma_m * options.site_sigma_m * Eigen::Matrix3d::Identity();
      }
      turn_levers_en.push_back(orbital_grid.EastNorthPerPixel(p.orbital_px) *
                               match.TurnLeverPx(template_px));
      out.push_back(std::move(p));
    }
  }
  ShareMatchCovariance(match, turn_levers_en, body, out);
  return out;
}

nlohmann::json ControlPointsJson(const std::vector<OrbitalControlPoint>& points) {
  nlohmann::json out = nlohmann::json::array();
  for (const OrbitalControlPoint& p : points) {
    nlohmann::json j = {
        {"id", p.point.id},
        {"source", p.point.source},
        {"ortho_px", {p.ortho_px.x(), p.ortho_px.y()}},
        {"orbital_px", {p.orbital_px.x(), p.orbital_px.y()}},
        {"lat_deg", DegFromRad(p.geographic.lat)},
        {"lon_deg", DegFromRad(p.geographic.lon)},
        {"h_m", p.geographic.h},
        {"height_from_dtm", p.height_from_dtm},
        {"sigma_east_m", p.sigma_east_m},
        {"sigma_north_m", p.sigma_north_m},
        {"sigma_up_m", p.sigma_up_m},
        {"false_match_probability", p.false_match_probability},
        {"mbf_m", {p.point.position_mbf.x(), p.point.position_mbf.y(), p.point.position_mbf.z()}},
        {"covariance_mbf_m2", MatrixJson(p.point.covariance_mbf)},
    };
    if (p.point.site >= 0) {
      j["site"] = p.point.site;
      const Eigen::Vector3d& s = p.point.position_in_site;
      j["position_in_site_m"] = {s.x(), s.y(), s.z()};
      j["covariance_in_site_m2"] = MatrixJson(p.point.covariance_in_site);
    }
    out.push_back(std::move(j));
  }
  return out;
}

std::string ControlPointsCsv(const std::vector<OrbitalControlPoint>& points) {
  std::ostringstream out;
  out << "id,site,ortho_col,ortho_row,orbital_col,orbital_row,lat_deg,lon_deg,h_m,"
         "sigma_east_m,sigma_north_m,sigma_up_m,false_match_probability,mbf_x_m,mbf_y_m,mbf_z_m,"
         "site_x_m,site_y_m,"
         "site_z_m\n";
  out << std::setprecision(12);
  for (const OrbitalControlPoint& p : points) {
    const Eigen::Vector3d& m = p.point.position_mbf;
    const Eigen::Vector3d& s = p.point.position_in_site;
    out << p.point.id << "," << p.point.site << "," << p.ortho_px.x() << "," << p.ortho_px.y()
        << "," << p.orbital_px.x() << "," << p.orbital_px.y() << "," << DegFromRad(p.geographic.lat)
        << "," << DegFromRad(p.geographic.lon) << "," << p.geographic.h << "," << p.sigma_east_m
        << "," << p.sigma_north_m << "," << p.sigma_up_m << "," << p.false_match_probability << ","
        << m.x() << "," << m.y() << "," << m.z();
    if (p.point.site >= 0) {
      out << "," << s.x() << "," << s.y() << "," << s.z() << "\n";
    } else {
      out << ",,,\n";
    }
  }
  return out.str();
}

nlohmann::json MatchJson(const OrbitalMatch& m) {
  nlohmann::json j = {
      {"orbital", m.orbital},
      {"matched", m.matched},
      {"reason", m.reason},
      {"overlaps", m.overlaps},
      {"window_clipped", m.window_clipped},
      {"correlation", Number(m.correlation)},
      {"peak_ratio", Number(m.peak_ratio)},
      {"sharpness", Number(m.sharpness)},
      {"false_match_probability", Number(m.false_match_probability)},
      {"chance_level",
       {{"peak_z", Number(m.peak_z)},
        {"expected_chance_peaks", Number(m.expected_chance_peaks)},
        {"null_samples", m.null.samples},
        {"null_mean", Number(m.null.mean)},
        {"null_stddev", Number(m.null.stddev)},
        {"null_lambda_x", Number(m.null.lambda_x)},
        {"null_lambda_y", Number(m.null.lambda_y)},
        {"pyramid_level", m.null_level}}},
      {"parts_tested", m.parts_tested},
      {"part_contradiction", Number(m.part_contradiction)},
      {"gsd_m", m.gsd_m},
      {"pyramid_levels", m.levels},
      {"search_radius_px", m.search_radius_px},
      {"template_pixels", m.template_pixels},
  };
  if (m.overlaps && m.template_pixels > 0) {
    j["shift_px"] = {m.shift_px.x(), m.shift_px.y()};
    j["shift_east_m"] = m.shift_en_m.x();
    j["shift_north_m"] = m.shift_en_m.y();
    j["sigma_east_m"] = Number(std::sqrt(m.shift_covariance_en_m2(0, 0)));
    j["sigma_north_m"] = Number(std::sqrt(m.shift_covariance_en_m2(1, 1)));
    j["corrected_lat_deg"] = DegFromRad(m.corrected_position.lat);
    j["corrected_lon_deg"] = DegFromRad(m.corrected_position.lon);
    if (m.rotation_solved) {
      j["rotation_deg"] = DegFromRad(m.rotation_rad);
      j["rotation_sigma_deg"] = Number(DegFromRad(m.rotation_sigma_rad));
    }
    if (m.scale_solved) j["scale"] = m.scale;
    j["relative_sharpness"] = Number(m.relative_sharpness);
  }
  if (m.expected_shift_px != Eigen::Vector2d::Zero()) {
    j["expected_shift_px"] = {m.expected_shift_px.x(), m.expected_shift_px.y()};
  }
  if (m.null_windows > 0) {
    j["null_windows"] = m.null_windows;
    j["null_reaching"] = m.null_reaching;
    j["null_highest_correlation"] = Number(m.null_highest);
  }
  return j;
}

GeoTransform CorrectedGeoTransform(const OrbitalMatch& match, const OrthoImage& ortho,
                                   const OrbitalImage& orbital) {
  const PixelGrid ortho_grid(ortho.geotransform, ortho.crs_wkt, ortho.source);
  const PixelGrid orbital_grid(orbital.geotransform(), orbital.crs_wkt(), orbital.name());
  const GridMapping to_orbital(ortho_grid, orbital_grid);
  const Eigen::Vector2d t0(match.templ.col0, match.templ.row0);
  Eigen::MatrixXd a(0, 3);
  Eigen::VectorXd bx(0), by(0);
  std::vector<Eigen::RowVector3d> rows;
  std::vector<Eigen::Vector2d> targets;
  for (int i = 0; i <= 4; ++i) {
    for (int j = 0; j <= 4; ++j) {
      const Eigen::Vector2d p(ortho.image.cols * j / 4.0, ortho.image.rows * i / 4.0);
      const Eigen::Vector2d v = match.TemplateToOrbital(to_orbital.Apply(p) - t0);
      const auto g = orbital_grid.PixelToGeographic(v);
      if (!g) continue;
      const Eigen::Vector2d q = ortho_grid.GeographicToPixel(*g);
      if (!q.allFinite()) continue;
      rows.emplace_back(1.0, p.x(), p.y());
      targets.push_back(ortho.geotransform.PixelToMap(q.x(), q.y()));
    }
  }
  if (rows.size() < 3) {
    throw Error(ortho.source + ": cannot map the orthophoto's grid onto " + orbital.name());
  }
  a.resize(static_cast<Eigen::Index>(rows.size()), 3);
  bx.resize(a.rows());
  by.resize(a.rows());
  for (size_t k = 0; k < rows.size(); ++k) {
    a.row(static_cast<Eigen::Index>(k)) = rows[k];
    bx(static_cast<Eigen::Index>(k)) = targets[k].x();
    by(static_cast<Eigen::Index>(k)) = targets[k].y();
  }
  const Eigen::Vector3d cx = a.colPivHouseholderQr().solve(bx);
  const Eigen::Vector3d cy = a.colPivHouseholderQr().solve(by);
  return GeoTransform{{cx(0), cx(1), cx(2), cy(0), cy(1), cy(2)}};
}

cv::Mat CorrelationSurfaceImage(const OrbitalMatch& match, int zoom) {
  const cv::Mat& s = match.surface;
  if (s.empty()) return {};
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int r = 0; r < s.rows; ++r) {
    for (int c = 0; c < s.cols; ++c) {
      const float v = s.at<float>(r, c);
      if (!std::isfinite(v)) continue;
      lo = std::min(lo, static_cast<double>(v));
      hi = std::max(hi, static_cast<double>(v));
    }
  }
  cv::Mat gray(s.size(), CV_8U, cv::Scalar(0));
  const double span = hi > lo ? hi - lo : 1.0;
  for (int r = 0; r < s.rows; ++r) {
    for (int c = 0; c < s.cols; ++c) {
      const float v = s.at<float>(r, c);
      if (std::isfinite(v))
        gray.at<uchar>(r, c) = cv::saturate_cast<uchar>(255.0 * (v - lo) / span);
    }
  }
  cv::Mat color;
  cv::applyColorMap(gray, color, cv::COLORMAP_VIRIDIS);
  color.setTo(cv::Scalar(0, 0, 0), NanMask(s));
  cv::resize(color, color, cv::Size(), zoom, zoom, cv::INTER_NEAREST);
  const double unit = static_cast<double>(1 << match.levels);
  const Eigen::Vector2d peak = (match.shift_px - match.surface_shift0) / unit;
  cv::circle(color,
             cv::Point(static_cast<int>((peak.x() + 0.5) * zoom),
                       static_cast<int>((peak.y() + 0.5) * zoom)),
             3 * zoom, cv::Scalar(0, 0, 255), std::max(1, zoom / 2));
  cv::cvtColor(color, color, cv::COLOR_BGR2RGB);
  return color;
}

}  // namespace areomap
