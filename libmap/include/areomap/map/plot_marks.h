// Marks on the plots that areomap writes (rock top views, traverse maps): a scale bar.
//
// Frame: image pixels (x right, y down). Colours: white outlined in black, so that the marks
// read on dark and light backgrounds alike and in RGB or BGR images.
#pragma once

#include <opencv2/core.hpp>

namespace areomap::internal {

// A bar of a round length (1, 2 or 5 x 10^k m) near a fifth of the image's width, labelled
// above, with its right end at `right_end`; `pixels_per_m` > 0.
void DrawScaleBar(cv::Mat* image, cv::Point right_end, double pixels_per_m);

}  // namespace areomap::internal
