// Line plots of the localization error study (RE against convergence angle, as Figs. 4.2-4.5),
// drawn with OpenCV into an 8-bit BGR image: axes with ticks, one coloured curve per series and a
// legend. Non-finite samples are skipped. Throws areomap::Error for an empty plot or a series
// whose x and y lengths differ.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/landmarks/localization_error.h"

namespace areomap {

struct PlotSeries {
  std::string label;
  std::vector<double> x, y;
};

// `y_max`, when finite, caps the y axis (curves above it leave the frame, clipped).
cv::Mat RenderLinePlot(const std::vector<PlotSeries>& series, const std::string& title,
                       const std::string& x_label, const std::string& y_label,
                       double y_max_cap = std::numeric_limits<double>::infinity(),
                       cv::Size size = cv::Size(900, 600));

// One plot per traverse length: a curve per landmark count (the study's samples of that length),
// y from 0 to 2.5 times the largest of the curves' minima (two landmarks soar at wide angles).
cv::Mat RenderConfigurationPlot(const std::vector<ConfigurationSample>& samples,
                                double traverse_length_m);

}  // namespace areomap
