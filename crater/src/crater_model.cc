#include "areomap/crater/crater_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "areomap/map/error.h"

namespace areomap {
namespace {

double Sample(const cv::Mat& m, const Eigen::Vector2d& p) {
  const double fx = p.x() - 0.5, fy = p.y() - 0.5;
  const int c = static_cast<int>(std::floor(fx)), r = static_cast<int>(std::floor(fy));
  if (c < 0 || r < 0 || c + 1 >= m.cols || r + 1 >= m.rows) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  const double tx = fx - c, ty = fy - r;
  return (1 - ty) * ((1 - tx) * m.at<float>(r, c) + tx * m.at<float>(r, c + 1)) +
         ty * ((1 - tx) * m.at<float>(r + 1, c) + tx * m.at<float>(r + 1, c + 1));
}

}  // namespace

std::optional<CraterModel> MeasureCraterOnDtm(const cv::Mat& dtm, const Ellipse& rim_px,
                                              double posting) {
  RequireOption(std::isfinite(posting) && posting > 0.0, "MeasureCraterOnDtm.posting", "> 0");
  if (dtm.channels() != 1) throw Error("crater model: expected a single-band DTM");
  if (!rim_px.IsValid()) return std::nullopt;
  cv::Mat h;
  dtm.convertTo(h, CV_32F);
  const Ellipse& e = rim_px;
  const double cs = std::cos(e.angle), sn = std::sin(e.angle);
  const auto point = [&](double rho, double t) {
    const double u = rho * e.semi_major * std::cos(t), v = rho * e.semi_minor * std::sin(t);
    return Eigen::Vector2d(e.center.x() + cs * u - sn * v, e.center.y() + sn * u + cs * v);
  };
  constexpr int kRimSamples = 72;
  std::vector<double> rim;
  for (int k = 0; k < kRimSamples; ++k) {
    const double t = 2.0 * std::numbers::pi * k / kRimSamples;
    double crest = -std::numeric_limits<double>::infinity();
    for (double rho = 0.92; rho <= 1.0801; rho += 0.02) {
      const double v = Sample(h, point(rho, t));
      if (std::isfinite(v)) crest = std::max(crest, v);
    }
    if (std::isfinite(crest)) rim.push_back(crest);
  }
  if (static_cast<int>(rim.size()) < kRimSamples * 3 / 4) return std::nullopt;
  // Interior pixels inside 0.9 x the rim.
  std::vector<double> inside;
  const double reach = e.semi_major;
  const int c0 = std::max(0, static_cast<int>(e.center.x() - reach));
  const int c1 = std::min(h.cols - 1, static_cast<int>(e.center.x() + reach));
  const int r0 = std::max(0, static_cast<int>(e.center.y() - reach));
  const int r1 = std::min(h.rows - 1, static_cast<int>(e.center.y() + reach));
  for (int r = r0; r <= r1; ++r) {
    for (int c = c0; c <= c1; ++c) {
      const double dx = c + 0.5 - e.center.x(), dy = r + 0.5 - e.center.y();
      const double u = (cs * dx + sn * dy) / e.semi_major, v = (-sn * dx + cs * dy) / e.semi_minor;
      if (u * u + v * v > 0.81) continue;
      const float value = h.at<float>(r, c);
      if (std::isfinite(value)) inside.push_back(value);
    }
  }
  const double interior_area = std::numbers::pi * 0.81 * e.semi_major * e.semi_minor;
  if (inside.empty() || static_cast<double>(inside.size()) < 0.5 * interior_area) {
    return std::nullopt;
  }
  CraterModel m;
  m.semi_major = e.semi_major * posting;
  m.semi_minor = e.semi_minor * posting;
  m.mean_radius = e.MeanRadius() * posting;
  m.eccentricity = e.Eccentricity();
  m.rim_height_max = *std::max_element(rim.begin(), rim.end());
  double sum = 0.0;
  for (double v : rim) sum += v;
  m.rim_height_mean = sum / static_cast<double>(rim.size());
  m.floor_height_min = *std::min_element(inside.begin(), inside.end());
  const double floor_limit = m.floor_height_min + 0.1 * (m.rim_height_mean - m.floor_height_min);
  double floor_sum = 0.0;
  int floor_count = 0;
  for (double v : inside) {
    if (v <= floor_limit) {
      floor_sum += v;
      ++floor_count;
    }
  }
  m.floor_height_mean = floor_sum / floor_count;
  m.depth_max_min = m.rim_height_max - m.floor_height_min;
  m.depth_mean = m.rim_height_mean - m.floor_height_mean;
  m.floor_radius = std::sqrt(floor_count / std::numbers::pi) * posting;
  m.ratio1 = e.semi_minor / e.semi_major;
  m.ratio2 = m.floor_radius / m.mean_radius;
  m.ratio3 = m.depth_max_min / m.mean_radius;
  return m;
}

}  // namespace areomap
