#include "areomap/map/plot_marks.h"

#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

namespace areomap::internal {

void DrawScaleBar(cv::Mat* image, cv::Point right_end, double pixels_per_m) {
  const double target_m = 0.2 * image->cols / pixels_per_m;
  const double decade = std::pow(10.0, std::floor(std::log10(target_m)));
  double length_m = decade;
  for (const double step : {2.0, 5.0, 10.0}) {
    if (step * decade <= target_m) length_m = step * decade;
  }
  const int length_px = static_cast<int>(std::lround(length_m * pixels_per_m));
  const cv::Point left_end = right_end - cv::Point(length_px, 0);
  char label[32];
  std::snprintf(label, sizeof(label), "%g m", length_m);
  // Black underneath, white on top.
  for (const auto& [colour, extra] :
       {std::pair{cv::Scalar(0, 0, 0), 2}, {cv::Scalar(255, 255, 255), 0}}) {
    cv::line(*image, left_end, right_end, colour, 2 + extra);
    cv::line(*image, left_end - cv::Point(0, 4), left_end + cv::Point(0, 4), colour, 2 + extra);
    cv::line(*image, right_end - cv::Point(0, 4), right_end + cv::Point(0, 4), colour, 2 + extra);
    cv::putText(*image, label, left_end + cv::Point(0, -8), cv::FONT_HERSHEY_SIMPLEX, 0.5, colour,
                1 + extra, cv::LINE_AA);
  }
}

}  // namespace areomap::internal
