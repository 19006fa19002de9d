// Rim edge points for crater detection: sub-pixel Canny edges of an image (gradient direction
// kept) and crest (ridge) points of a DTM from its curvature (Bue & Stepinski 2007, ch. 2.2.1).
//
// Frame: pixel coordinates of the input raster in GDAL's convention (pixel (col, row) covers
// [col, col + 1) x [row, row + 1), its centre is (col + 0.5, row + 0.5)), x right, y down.
// Non-finite input pixels (nodata holes) never produce edges, nor do pixels next to them.
// Nothing here throws for image content; a constant or empty image gives no edges.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

namespace areomap {

struct RimEdgePoint {
  float x = 0.0f;         // sub-pixel position [px]
  float y = 0.0f;         // [px]
  float nx = 0.0f;        // unit normal: image gradient direction (towards brighter), or for a DTM
  float ny = 0.0f;        // crest the direction of strongest downward curvature (sign arbitrary)
  float strength = 0.0f;  // gradient magnitude [DN/px]; DTM: -curvature / posting
};

struct RimEdges {
  // In raster order: by pixel row, then pixel column (at most one point per pixel).
  std::vector<RimEdgePoint> points;
  // The pixel of each point, as compressed rows: the points of pixel row r are
  // points[row_start[r] .. row_start[r + 1]), `column` holds their pixel columns (increasing).
  std::vector<int> row_start;  // rows + 1 entries
  std::vector<int> column;     // one per point
  int rows = 0;                // raster size [px]
  int cols = 0;
  bool signed_normals = true;   // true for image edges (polarity known), false for DTM crests
  double high_threshold = 0.0;  // automatic hysteresis thresholds used [strength unit]
  double low_threshold = 0.0;

  // Index into `points` of the first point in pixel row `row` whose column is >= `col`
  // (row_start[row + 1] when none); `row` in [0, rows).
  int FirstInRow(int row, int col) const;
};

struct EdgeOptions {
  double smoothing_sigma_px = 0.8;  // Gaussian pre-smoothing [px] (> 0)
  // Automatic hysteresis thresholds: high = max(high_quantile of the strength over valid pixels,
  // noise_factor x the Rayleigh noise level from the median strength); low = low_ratio x high.
  double high_quantile = 0.80;
  double noise_factor = 2.5;
  double low_ratio = 0.45;

  void Check() const;  // throws areomap::Error naming the bad field
};

// The gradients the image edges are found on: `image` (CV_32F, single band, finite) smoothed by
// a Gaussian of `sigma_px` (in (0, 10]; cv::GaussianBlur's kernel for float images, of
// round(8 sigma + 1) taps made odd), its 3 x 3 Sobel derivatives / 8 (`gx` towards +x, `gy`
// towards +y) and their magnitude, each CV_32F of the image's size (reallocated unless they
// already are). The values of cv::GaussianBlur, cv::Sobel and cv::magnitude up to float rounding:
// like GaussianBlur, a view reads its parent image beyond its border (reflected at the parent's
// border: BORDER_REFLECT_101), and the derivatives reflect at the view's own border, like Sobel of
// the smoothed view. One pass over the rows: the smoothed image is never stored. Throws
// areomap::Error for another image type or sigma.
void SmoothedImageGradients(const cv::Mat& image, double sigma_px, cv::Mat* gx, cv::Mat* gy,
                            cv::Mat* magnitude);

// Canny on a single-band image (any depth; NaN = nodata) with thresholds chosen from the
// image's own gradient statistics, edges localised to sub-pixel along the gradient by a
// parabola through the magnitude, gradient direction kept.
RimEdges DetectImageEdges(const cv::Mat& image, const EdgeOptions& options = {});

// DetectImageEdges restricted to `regions` (rectangles inside the image, [px]): the edges of the
// pixels in them, in image coordinates and raster order. The image is cut into bands of 64 rows;
// in each, the regions' parts less than 64 px apart along the row share a window, computed with
// a 4 px margin of the image around it. The thresholds are the automatic ones of the whole
// image, estimated on strips of 6 rows every 72 rows (1/12 of the samples) instead of the whole
// image: they do not depend on the regions. Inside the regions the edges are those of
// DetectImageEdges but for the thresholds' sampling, the 16-bit gradient rounding (scaled to
// each window's largest gradient), nodata filled with each window's mean, and hysteresis
// followed at most 4 px beyond a window (so also across a band's cut). For a search that only
// some parts of a large image need: the work is that of the windows plus the strips. Throws
// areomap::Error when a region leaves the image or has a negative size; an empty region selects
// nothing; overlapping regions give each pixel's point once.
RimEdges DetectImageEdgesInRegions(const cv::Mat& image, const std::vector<cv::Rect>& regions,
                                   const EdgeOptions& options = {});

// Crest points of a DTM (heights, NaN = nodata): pixels where the Hessian's most negative
// eigenvalue (profile curvature across a rim) is a local maximum of -curvature along its
// eigenvector, above automatic hysteresis thresholds. `posting` only scales `strength` into
// height units per ground unit squared.
RimEdges DetectDtmCrests(const cv::Mat& dtm, double posting, const EdgeOptions& options = {});

}  // namespace areomap
