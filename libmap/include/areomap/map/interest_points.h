// Förstner interest operator (Förstner & Gülch 1987), the point detector the dissertation uses
// for stereo tie points (ch. 2.2.2). For every pixel the gradient structure tensor N is summed
// over a square window; the operator's weight w = det N / tr N (the size of the error ellipse's
// inverse) and roundness q = 4 det N / (tr N)^2 in [0, 1] (1: an isotropic corner, 0: a straight
// edge). Points are the local maxima of w with q >= min_roundness and w >= weight_factor times
// the image's mean w, located to sub-pixel by Förstner's least-squares corner (the point nearest
// to all edge lines in the window), one per suppression radius, and thinned to the strongest few
// per grid cell so they spread over the image.
//
// Pixels: (column, row), first pixel centre at (0, 0). Images: single-channel CV_8U, CV_16U or
// CV_32F (NaN pixels are treated as 0 and their neighbourhood gives no points); anything else
// throws areomap::Error. An image without corners gives an empty list.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

namespace areomap {

struct ForstnerOptions {
  int half_window = 2;            // Tensor summed over (2 h + 1)^2 px.
  double min_roundness = 0.5;     // q threshold (Förstner's usual 0.5-0.75).
  double weight_factor = 1.5;     // w threshold as a multiple of the mean w (0.5-1.5 usual).
  int suppression_radius_px = 4;  // Non-maximum suppression over (2 r + 1)^2 px.
  int grid_cells = 16;            // The image is split into grid_cells^2 cells...
  int max_points_per_cell = 8;    // ...each keeping its strongest points.
  void Check() const;             // Throws areomap::Error naming the field.
};

struct InterestPoint {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();
  double weight = 0.0;     // w = det N / tr N [grey level^2]
  double roundness = 0.0;  // q in [0, 1]
};

// Strongest first.
std::vector<InterestPoint> DetectForstnerPoints(const cv::Mat& image,
                                                const ForstnerOptions& options = {});

}  // namespace areomap
