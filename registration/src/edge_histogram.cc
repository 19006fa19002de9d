#include "areomap/registration/edge_histogram.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

namespace areomap {
namespace {

constexpr int kPanelWidth = 360;
constexpr int kPanelHeight = 170;
constexpr int kMargin = 34;

void DrawPanel(cv::Mat& canvas, cv::Point origin, const std::vector<int>& counts,
               double max_difference, const std::string& title, const std::string& unit) {
  const cv::Scalar black(0, 0, 0), bar(180, 110, 40), grey(150, 150, 150);
  const int w = kPanelWidth - 2 * kMargin, h = kPanelHeight - 2 * kMargin;
  const cv::Point x0 = origin + cv::Point(kMargin, kMargin + h);
  const int top = std::max(1, *std::max_element(counts.begin(), counts.end()));
  const int n = static_cast<int>(counts.size());
  for (int k = 0; k < n; ++k) {
    const int bh = static_cast<int>(std::lround(static_cast<double>(counts[k]) / top * h));
    const int left = x0.x + k * w / n, right = x0.x + (k + 1) * w / n - 1;
    cv::rectangle(canvas, cv::Point(left, x0.y - bh), cv::Point(right, x0.y), bar, cv::FILLED);
  }
  cv::line(canvas, x0, x0 + cv::Point(w, 0), black);
  cv::line(canvas, x0, x0 - cv::Point(0, h), black);
  for (int tick = 0; tick <= 5; ++tick) {
    const int x = x0.x + tick * w / 5;
    cv::line(canvas, {x, x0.y}, {x, x0.y + 4}, black);
    cv::putText(canvas, std::to_string(static_cast<int>(std::lround(tick * max_difference / 5))),
                {x - 4, x0.y + 16}, cv::FONT_HERSHEY_PLAIN, 0.9, black);
  }
  cv::putText(canvas, std::to_string(top), {x0.x - 30, x0.y - h + 4}, cv::FONT_HERSHEY_PLAIN, 0.9,
              grey);
  cv::putText(canvas, title, origin + cv::Point(kMargin, kMargin - 10), cv::FONT_HERSHEY_PLAIN, 1.0,
              black);
  cv::putText(canvas, unit, {x0.x + w - 60, x0.y + 30}, cv::FONT_HERSHEY_PLAIN, 0.9, black);
}

}  // namespace

cv::Mat WorldViewVectorHistogramImage(const EdgeVerification& verification, double max_difference,
                                      int bins) {
  bins = std::max(bins, 1);
  cv::Mat canvas(4 * kPanelHeight, 2 * kPanelWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  const char* groups[] = {"0 px", "(0, 1] px", "(1, 2] px", "(2, 3] px"};
  for (int g = 0; g < 4; ++g) {
    std::vector<int> radius(bins, 0), angle(bins, 0);
    int n = 0;
    for (const EdgePair& p : verification.pairs) {
      if (p.group != g || !std::isfinite(p.wvv_radius_diff_px)) continue;
      const auto bin = [&](double v) {
        return std::clamp(static_cast<int>(v / max_difference * bins), 0, bins - 1);
      };
      ++radius[bin(p.wvv_radius_diff_px)];
      ++angle[bin(p.wvv_angle_diff_deg)];
      ++n;
    }
    const std::string title =
        std::string("group ") + groups[g] + ", " + std::to_string(n) + " pairs: ";
    DrawPanel(canvas, {0, g * kPanelHeight}, radius, max_difference, title + "radius diff",
              "pixel");
    DrawPanel(canvas, {kPanelWidth, g * kPanelHeight}, angle, max_difference, title + "angle diff",
              "deg");
  }
  return canvas;
}

}  // namespace areomap
