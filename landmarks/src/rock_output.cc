// Rock catalogues and matches as CSV and JSON files.
#include "areomap/landmarks/rock_output.h"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include <algorithm>

#include <Eigen/Eigenvalues>
#include <opencv2/imgproc.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/plot_marks.h"

namespace areomap {

namespace {

std::string Number(double value, const char* format = "%.4f") {
  if (!std::isfinite(value)) return "";
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), format, value);
  return buffer;
}

nlohmann::json Vector3Json(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json ModelJson(const RockModelFit& fit) {
  const RockModelParameters& p = fit.parameters;
  nlohmann::json sigma = nlohmann::json::array();
  for (double s : fit.sigma) sigma.push_back(s);
  return {{"shape", ToString(p.shape)},
          {"converged", fit.converged},
          {"complex", fit.complex_model},
          {"points", fit.point_count},
          {"rms_m", fit.rms_m},
          {"height_m", p.height},
          {"a_m", p.a},
          {"b_m", p.b},
          {"phi_rad", p.phi},
          {"alpha_rad", p.alpha},
          {"beta_rad", p.beta},
          {"center_m", {p.center_x, p.center_y}},
          {"volume_m3", p.Volume()},
          {"surface_area_m2", p.SurfaceAreaExact()},
          {"surface_area_approx_m2", p.SurfaceAreaApprox()},
          {"sigma", sigma},
          {"message", fit.message}};
}

// A rock's colour in the plots (RGB): red when modeled, orange when not.
cv::Scalar RockColour(const ExtractedRock& rock) {
  return rock.modeled() ? cv::Scalar(255, 0, 0) : cv::Scalar(255, 165, 0);
}

// Grey level of an elevation at fraction t in [0, 1] of the plotted range, before viridis: 40..255
// (0 stays black, the background).
uint8_t ElevationGrey(double t) { return static_cast<uint8_t>(40 + 215 * t); }

// The elevation colour ramp (grey levels 40..255 of viridis, as the points) from `lo` to `hi`
// metres, 150 x 10 px with its top left corner at `corner`, labelled at both ends.
void DrawElevationRamp(cv::Mat* image, cv::Point corner, double lo, double hi) {
  cv::Mat ramp(1, 150, CV_8UC1);
  for (int i = 0; i < ramp.cols; ++i) ramp.at<uint8_t>(0, i) = ElevationGrey(i / 149.0);
  cv::Mat colours;
  cv::applyColorMap(ramp, colours, cv::COLORMAP_VIRIDIS);
  cv::cvtColor(colours, colours, cv::COLOR_BGR2RGB);
  cv::resize(colours, colours, cv::Size(150, 10), 0, 0, cv::INTER_NEAREST);
  colours.copyTo((*image)(cv::Rect(corner, cv::Size(150, 10))));
  const cv::Scalar white(255, 255, 255);
  char text[48];
  std::snprintf(text, sizeof(text), "%.2f m", lo);
  cv::putText(*image, text, corner + cv::Point(0, -4), cv::FONT_HERSHEY_SIMPLEX, 0.4, white, 1);
  std::snprintf(text, sizeof(text), "%.2f m", hi);
  cv::putText(*image, text, corner + cv::Point(110, -4), cv::FONT_HERSHEY_SIMPLEX, 0.4, white, 1);
}

}  // namespace

nlohmann::json RockToJson(const ExtractedRock& rock) {
  nlohmann::json covariance = nlohmann::json::array();
  for (int r = 0; r < 3; ++r) {
    covariance.push_back(
        {rock.peak_covariance(r, 0), rock.peak_covariance(r, 1), rock.peak_covariance(r, 2)});
  }
  nlohmann::json models = nlohmann::json::array();
  for (const RockModelFit& fit : rock.models) models.push_back(ModelJson(fit));
  return {{"id", rock.id},
          {"peak_m", Vector3Json(rock.peak)},
          {"peak_covariance_m2", covariance},
          {"range_m", rock.range_m},
          {"height_m", rock.height_m},
          {"plane_normal", Vector3Json(rock.plane_normal)},
          {"peak_foot_m", Vector3Json(rock.peak_foot)},
          {"background_points", rock.background_points},
          {"ground_sigma_m", rock.ground_sigma_m},
          {"surface_points", rock.surface_indices.size()},
          {"surface_radius_m", rock.surface_radius_m},
          {"modeled", rock.modeled()},
          {"models", models}};
}

nlohmann::json RockExtractionSummaryToJson(const RockExtractionSummary& s) {
  return {{"points", s.points},
          {"peak_candidates", s.peak_candidates},
          {"beyond_range", s.beyond_range},
          {"too_low", s.too_low},
          {"merged", s.merged},
          {"rocks", s.rocks},
          {"modeled", s.modeled}};
}

void WriteRocksCsv(const std::filesystem::path& path, const std::vector<ExtractedRock>& rocks) {
  std::ostringstream out;
  out << "id,x_m,y_m,z_m,sigma_x_m,sigma_y_m,sigma_z_m,range_m,height_m,normal_x,normal_y,"
         "normal_z,surface_points,ground_sigma_m,model,model_height_m,model_a_m,model_b_m,"
         "model_rms_m,volume_m3,surface_area_m2\n";
  for (const ExtractedRock& r : rocks) {
    out << r.id << ',' << Number(r.peak.x()) << ',' << Number(r.peak.y()) << ','
        << Number(r.peak.z()) << ',' << Number(std::sqrt(r.peak_covariance(0, 0))) << ','
        << Number(std::sqrt(r.peak_covariance(1, 1))) << ','
        << Number(std::sqrt(r.peak_covariance(2, 2))) << ',' << Number(r.range_m, "%.3f") << ','
        << Number(r.height_m) << ',' << Number(r.plane_normal.x(), "%.5f") << ','
        << Number(r.plane_normal.y(), "%.5f") << ',' << Number(r.plane_normal.z(), "%.5f") << ','
        << r.surface_indices.size() << ',' << Number(r.ground_sigma_m);
    if (const RockModelFit* m = r.best_model()) {
      const RockModelParameters& p = m->parameters;
      out << ',' << ToString(p.shape) << ',' << Number(p.height) << ',' << Number(p.a) << ','
          << Number(p.b) << ',' << Number(m->rms_m, "%.5f") << ',' << Number(p.Volume(), "%.6f")
          << ',' << Number(p.SurfaceAreaExact(), "%.5f");
    } else {
      out << ",,,,,,,";
    }
    out << '\n';
  }
  WriteFileAtomically(path, out.str());
}

void WriteRocksJson(const std::filesystem::path& path, const std::vector<ExtractedRock>& rocks) {
  nlohmann::json list = nlohmann::json::array();
  for (const ExtractedRock& r : rocks) list.push_back(RockToJson(r));
  WriteFileAtomically(
      path,
      nlohmann::json{{"frame", "site (x north, y east, z down) [m]"}, {"rocks", list}}.dump(2) +
          "\n");
}

void WriteRockMatchesCsv(const std::filesystem::path& path, const SiteRocks& a, const SiteRocks& b,
                         const SitePairMatch& match) {
  std::ostringstream out;
  out << "rock_a,rock_b,xa_m,ya_m,za_m,xb_m,yb_m,zb_m,sigma_a_m,sigma_b_m,model_cost,"
         "pattern_votes,normal_angle_deg,distance_ratio\n";
  const auto horizontal_sigma = [](const ExtractedRock& r) {
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(
        r.peak_covariance.topLeftCorner<2, 2>());
    return std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
  };
  for (const RockMatch& m : match.matches) {
    const ExtractedRock& p = a.rocks.at(static_cast<size_t>(m.rock_a));
    const ExtractedRock& q = b.rocks.at(static_cast<size_t>(m.rock_b));
    out << p.id << ',' << q.id << ',' << Number(p.peak.x()) << ',' << Number(p.peak.y()) << ','
        << Number(p.peak.z()) << ',' << Number(q.peak.x()) << ',' << Number(q.peak.y()) << ','
        << Number(q.peak.z()) << ',' << Number(horizontal_sigma(p)) << ','
        << Number(horizontal_sigma(q)) << ',' << Number(m.model_cost) << ',' << m.pattern_count
        << ',' << Number(m.normal_angle_deg, "%.2f") << ',' << Number(m.distance_ratio, "%.3f")
        << '\n';
  }
  WriteFileAtomically(path, out.str());
}

void WriteRocksPlotPng(const std::filesystem::path& path, const PointCloud& cloud,
                       const std::vector<ExtractedRock>& rocks, double max_range_m, int pixels) {
  std::vector<const StereoPoint*> shown;
  for (const StereoPoint& p : cloud.points) {
    if ((p.position - cloud.camera_center).head<2>().norm() <= max_range_m) shown.push_back(&p);
  }
  if (shown.empty()) {
    // Nothing to draw is a result too (an empty cloud, or none of it in range): say so.
    cv::Mat empty(pixels, pixels, CV_8UC3, cv::Scalar(0, 0, 0));
    char note[160];
    std::snprintf(note, sizeof(note), "no point of the cloud within %.1f m of the camera",
                  max_range_m);
    cv::putText(empty, note, cv::Point(10, pixels / 2), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(255, 255, 255), 1);
    WriteImage(path, empty);
    return;
  }
  Eigen::Vector2d lo(1e300, 1e300), hi(-1e300, -1e300);
  std::vector<double> elevations;
  for (const StereoPoint* p : shown) {
    lo = lo.cwiseMin(p->position.head<2>());
    hi = hi.cwiseMax(p->position.head<2>());
    elevations.push_back(-p->position.z());
  }
  std::sort(elevations.begin(), elevations.end());
  const double e_lo = elevations[elevations.size() / 50];
  const double e_hi = std::max(e_lo + 1e-3, elevations[elevations.size() * 49 / 50]);
  const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1e-3});
  const double scale = (pixels - 40) / span;  // Pixels per metre, 20 px margins.
  // Image column from y (east / right), row from x (north / forward, up in the image).
  const auto to_pixel = [&](const Eigen::Vector3d& p) {
    return cv::Point(static_cast<int>(20 + (p.y() - lo.y()) * scale),
                     static_cast<int>(20 + (hi.x() - p.x()) * scale));
  };
  cv::Mat gray(pixels, pixels, CV_8UC1, cv::Scalar(0));
  for (const StereoPoint* p : shown) {
    const cv::Point q = to_pixel(p->position);
    if (q.x < 0 || q.y < 0 || q.x >= pixels || q.y >= pixels) continue;
    const double t = std::clamp((-p->position.z() - e_lo) / (e_hi - e_lo), 0.0, 1.0);
    gray.at<uint8_t>(q) = std::max<uint8_t>(gray.at<uint8_t>(q), ElevationGrey(t));
  }
  cv::Mat image;
  cv::applyColorMap(gray, image, cv::COLORMAP_VIRIDIS);
  cv::cvtColor(image, image, cv::COLOR_BGR2RGB);  // WriteImage takes RGB.
  image.setTo(cv::Scalar(0, 0, 0), gray == 0);
  cv::circle(image, to_pixel(cloud.camera_center), 6, cv::Scalar(255, 255, 255), cv::FILLED);
  for (const ExtractedRock& r : rocks) {
    if (r.range_m > max_range_m) continue;
    const cv::Scalar colour = RockColour(r);
    const int radius = std::max(4, static_cast<int>(std::max(r.surface_radius_m, 0.05) * scale));
    cv::circle(image, to_pixel(r.peak), radius, colour, 2);
    cv::putText(image, std::to_string(r.id), to_pixel(r.peak) + cv::Point(radius + 2, 0),
                cv::FONT_HERSHEY_SIMPLEX, 0.5, colour, 1);
  }
  if (pixels >= 400) {
    DrawElevationRamp(&image, cv::Point(10, pixels - 45), e_lo, e_hi);
    internal::DrawScaleBar(&image, cv::Point(pixels - 15, pixels - 30), scale);
  }
  char legend[160];
  std::snprintf(legend, sizeof(legend),
                "top view, x up, y right; %.1f m across; elevation %.2f..%.2f m; red: modeled",
                (pixels - 40) / scale, e_lo, e_hi);
  cv::putText(image, legend, cv::Point(10, pixels - 8), cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(255, 255, 255), 1);
  WriteImage(path, image);
}

cv::Mat RenderRocksImage(const cv::Mat& image, const PointCloud& cloud,
                         const std::vector<ExtractedRock>& rocks, int image_id,
                         const std::string& image_name) {
  if (image.empty() || image.channels() == 2 || image.channels() > 4) {
    throw Error(image_name + ": expected a grey, RGB or RGBA image to draw the rocks on");
  }
  cv::Mat rgb = image;
  if (rgb.channels() == 4) cv::cvtColor(rgb, rgb, cv::COLOR_RGBA2RGB);  // Alpha dropped first.
  if (rgb.depth() != CV_8U) cv::normalize(rgb, rgb, 0, 255, cv::NORM_MINMAX, CV_8U);
  if (rgb.channels() == 1) cv::cvtColor(rgb, rgb, cv::COLOR_GRAY2RGB);
  rgb = rgb.clone();
  const cv::Rect inside(0, 0, rgb.cols, rgb.rows);
  const auto pixel_of = [&](int index) {
    const StereoPoint& p = cloud.points[static_cast<size_t>(index)];
    return cv::Point(static_cast<int>(std::lround(p.left_x)),
                     static_cast<int>(std::lround(p.left_y)));
  };
  const auto from_pair = [&](int index) {
    return index >= 0 && static_cast<size_t>(index) < cloud.points.size() &&
           cloud.points[static_cast<size_t>(index)].image_id == image_id;
  };
  int painted = 0;
  for (const ExtractedRock& r : rocks) {
    const cv::Scalar colour = RockColour(r);
    const cv::Vec3b paint(static_cast<uint8_t>(colour[0]), static_cast<uint8_t>(colour[1]),
                          static_cast<uint8_t>(colour[2]));
    for (int index : r.surface_indices) {
      if (!from_pair(index)) continue;
      const cv::Point q = pixel_of(index);
      if (!inside.contains(q)) continue;
      rgb.at<cv::Vec3b>(q) = paint;
      ++painted;
    }
  }
  for (const ExtractedRock& r : rocks) {
    if (!from_pair(r.peak_index)) continue;
    const cv::Point peak = pixel_of(r.peak_index);
    if (!inside.contains(peak)) continue;
    ++painted;
    const cv::Scalar colour = RockColour(r);
    cv::drawMarker(rgb, peak, cv::Scalar(255, 255, 0), cv::MARKER_CROSS, 14, 2);
    char label[48];
    std::snprintf(label, sizeof(label), "%d: %.2f m", r.id, r.height_m);
    cv::putText(rgb, label, peak + cv::Point(9, -6), cv::FONT_HERSHEY_SIMPLEX, 0.5, colour, 1);
  }
  if (painted == 0 && !rocks.empty()) {
    throw Error(image_name + ": no rock point of pair " + std::to_string(image_id) +
                " falls inside the " + std::to_string(rgb.cols) + " x " + std::to_string(rgb.rows) +
                " image (is it the cloud's left image?)");
  }
  return rgb;
}

}  // namespace areomap
