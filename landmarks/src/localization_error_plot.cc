#include "areomap/landmarks/localization_error_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"

namespace areomap {

namespace {

std::string Format(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.3g", value);
  return text;
}

}  // namespace

cv::Mat RenderLinePlot(const std::vector<PlotSeries>& series, const std::string& title,
                       const std::string& x_label, const std::string& y_label, double y_max_cap,
                       cv::Size size) {
  double x_min = std::numeric_limits<double>::infinity(), x_max = -x_min;
  double y_min = x_min, y_max = -x_min;
  for (const PlotSeries& s : series) {
    if (s.x.size() != s.y.size()) {
      throw Error("plot series '" + s.label + "': x and y have different lengths");
    }
    for (size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) continue;
      x_min = std::min(x_min, s.x[i]);
      x_max = std::max(x_max, s.x[i]);
      y_min = std::min(y_min, s.y[i]);
      y_max = std::max(y_max, s.y[i]);
    }
  }
  if (!std::isfinite(x_min)) throw Error("plot '" + title + "': no finite samples");
  if (x_max == x_min) x_max = x_min + 1.0;
  if (y_max == y_min) y_max = y_min + 1.0;
  const double pad = 0.05 * (y_max - y_min);
  y_min = y_min >= 0.0 ? std::max(0.0, y_min - pad) : y_min - pad;
  y_max = std::min(y_max + pad, y_max_cap);
  if (y_max <= y_min) y_max = y_min + 1.0;
  cv::Mat image(size, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Rect area(90, 50, size.width - 260, size.height - 120);
  const auto to_pixel = [&](double x, double y) {
    return cv::Point(
        area.x + static_cast<int>(std::lround((x - x_min) / (x_max - x_min) * area.width)),
        area.y + area.height -
            static_cast<int>(std::lround((y - y_min) / (y_max - y_min) * area.height)));
  };
  const cv::Scalar black(0, 0, 0), grey(210, 210, 210);
  const int font = cv::FONT_HERSHEY_SIMPLEX;
  for (int k = 0; k <= 5; ++k) {
    const double x = x_min + (x_max - x_min) * k / 5.0, y = y_min + (y_max - y_min) * k / 5.0;
    const cv::Point px = to_pixel(x, y_min), py = to_pixel(x_min, y);
    cv::line(image, px, {px.x, area.y}, grey, 1);
    cv::line(image, py, {area.x + area.width, py.y}, grey, 1);
    cv::putText(image, Format(x), {px.x - 15, area.y + area.height + 22}, font, 0.5, black, 1,
                cv::LINE_AA);
    cv::putText(image, Format(y), {area.x - 70, py.y + 5}, font, 0.5, black, 1, cv::LINE_AA);
  }
  cv::rectangle(image, area, black, 1);
  cv::putText(image, title, {area.x, 30}, font, 0.7, black, 2, cv::LINE_AA);
  cv::putText(image, x_label, {area.x + area.width / 2 - 100, size.height - 25}, font, 0.6, black,
              1, cv::LINE_AA);
  cv::putText(image, y_label, {10, area.y - 12}, font, 0.6, black, 1, cv::LINE_AA);
  static const cv::Scalar kColours[] = {{200, 60, 30},  {40, 40, 220}, {40, 160, 40},
                                        {160, 40, 160}, {0, 140, 220}, {90, 90, 90}};
  cv::Mat inside = image(area);  // Curves are drawn into the frame, which clips them.
  for (size_t i = 0; i < series.size(); ++i) {
    const cv::Scalar colour = kColours[i % std::size(kColours)];
    std::vector<cv::Point> line;
    for (size_t k = 0; k < series[i].x.size(); ++k) {
      if (!std::isfinite(series[i].x[k]) || !std::isfinite(series[i].y[k])) continue;
      line.push_back(to_pixel(series[i].x[k], series[i].y[k]) - area.tl());
      cv::circle(inside, line.back(), 3, colour, cv::FILLED, cv::LINE_AA);
    }
    if (line.size() > 1) cv::polylines(inside, line, false, colour, 2, cv::LINE_AA);
    const cv::Point legend(area.x + area.width + 20, area.y + 20 + 28 * static_cast<int>(i));
    cv::line(image, legend, legend + cv::Point(30, 0), colour, 3);
    cv::putText(image, series[i].label, legend + cv::Point(40, 5), font, 0.55, black, 1,
                cv::LINE_AA);
  }
  return image;
}

cv::Mat RenderConfigurationPlot(const std::vector<ConfigurationSample>& samples,
                                double traverse_length_m) {
  std::map<int, PlotSeries> by_count;
  for (const ConfigurationSample& s : samples) {
    if (std::abs(s.traverse_length_m - traverse_length_m) > 1e-9) continue;
    PlotSeries& series = by_count[s.landmark_count];
    series.label = std::to_string(s.landmark_count) + " landmarks";
    series.x.push_back(s.convergence_deg);
    series.y.push_back(s.relative_error_percent);
  }
  std::vector<PlotSeries> series;
  double largest_minimum = 0.0;
  for (auto& [count, s] : by_count) {
    double minimum = std::numeric_limits<double>::infinity();
    for (double y : s.y) {
      if (std::isfinite(y)) minimum = std::min(minimum, y);
    }
    if (std::isfinite(minimum)) largest_minimum = std::max(largest_minimum, minimum);
    series.push_back(std::move(s));
  }
  return RenderLinePlot(
      series, "Relative localization error, Navcam, traverse " + Format(traverse_length_m) + " m",
      "convergence angle [deg]", "RE [%]",
      largest_minimum > 0.0 ? 2.5 * largest_minimum : std::numeric_limits<double>::infinity());
}

}  // namespace areomap
