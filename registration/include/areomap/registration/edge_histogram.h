// Fig. 3.15 of the dissertation as a picture: histograms of the world-view-vector differences
// (radius [px], polar angle [deg]) of the paired edge points, one row per distance group
// (0, (0, 1], (1, 2], (2, 3] px).
#pragma once

#include <opencv2/core.hpp>

#include "areomap/registration/edge_verify.h"

namespace areomap {

// RGB CV_8UC3 picture: 4 rows (groups) x 2 panels (radius, angle), `bins` bins over
// [0, max_difference]; differences beyond it go to the last bin. Pairs without world-view
// differences (NaN) are left out.
cv::Mat WorldViewVectorHistogramImage(const EdgeVerification& verification,
                                      double max_difference = 10.0, int bins = 20);

}  // namespace areomap
