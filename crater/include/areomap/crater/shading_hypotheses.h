// Crater hypotheses from the shading of a bowl under a known sun: a matched filter for small or
// degraded craters whose rims give too few edges for the edge-arc hypotheses of
// crater_detector.h.
//
// Physics: the interior of a bowl z = depth (r / R)^2 has the slope 2 depth d / R^2, so under a
// sun from the horizontal direction s its Lambertian brightness changes, to first order in the
// slope, linearly with -(d . s) / R across the bowl: the wall facing the sun (d . s < 0 is the
// far wall, lit) is bright, the sunward wall (d . s > 0, turned away) dark, the plain around flat.
// The rim shows edges only where the wall brightness meets the plain, i.e. along the sun line:
// at the sunward rim the plain is brighter than the dark wall, at the far rim the bright wall is
// brighter than the plain, so the gradient points towards the sun on both; across the sun line
// the wall is as bright as the plain and there is no edge. The template is that ramp inside a
// disc of radius R on a window of half-width 1.6 R with zero (flat plain) outside; its
// normalised cross-correlation with the image (TM_CCOEFF_NORMED of cv::matchTemplate, computed
// from one cv::filter2D and box sums) is
// invariant to the brightness scale and offset, and is low for a plain brightness ramp (0.30)
// or a straight step edge (0.47) filling the window.
//
// Frame: pixel coordinates of the input image, GDAL convention (pixel (col, row) covers
// [col, col + 1) x [row, row + 1)), x right, y down; lengths in pixels. Sun azimuth: degrees
// clockwise from the image's up direction, towards the sun (as CraterDetectorOptions).
//
// Failure: bad options throw areomap::Error naming the field; image content never throws (a
// constant image, nodata holes or no bowls give no hypotheses).
#pragma once

#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "areomap/crater/rim_edges.h"

namespace areomap {

struct CraterDetection;  // crater_detection.h

struct ShadingTemplateOptions {
  // Run the shading-template hypotheses in DetectCraters (image with a sun azimuth only).
  // Off by default: about 1.35x the detector's CPU time for a small gain on typical images
  // (docs/benchmarks.md); worth it on fields of degraded, shallow bowls (CLI --shading-templates).
  bool enabled = false;
  // Template radii per octave of crater size (each template covers +-1/(2 x this) octave).
  int radii_per_octave = 2;
  // Thresholds below were chosen on generated scenes of degraded bowls (docs/benchmarks.md).
  // Normalised cross-correlation with the bowl template: local maxima at least this high become
  // hypotheses, and a template-only crater needs it too. A straight step edge filling the
  // window scores 0.47, a bowl on a plain with little texture 0.8-0.95.
  double min_correlation = 0.6;
  // The template's least-squares amplitude at the peak, in robust standard deviations (1.4826
  // MAD about the median) of the same template's amplitude over the whole image: a constant
  // false alarm rate rule that adapts to how strongly the terrain's own texture resembles a
  // dipole at that scale. 5 sigma of a Gaussian background leaves about 3e-7 false peaks per
  // position and template.
  double min_significance = 5.0;
  // Brightness difference between the far (lit) and the sunward (dark) wall at the rim, from a
  // least-squares fit of the template ramp to the interior, over the standard deviation of the
  // surroundings (annulus 1.25-1.75 R): a bowl's walls stand out of the plain's texture.
  double min_dipole_contrast = 5.0;
  // Fraction of the rim near the sun line (the 16 of 36 sectors centred within 40 degrees of
  // it) holding a rim edge of bowl polarity (gradient towards the sun, normal radial within 37
  // degrees, within max(1.5 px, 0.15 R) of the circle): the rim break that a smooth depression
  // of the background lacks.
  double min_sun_line_coverage = 0.6;

  void Check() const;  // throws areomap::Error naming the bad field
};

// The zero-mean bowl template for radius `radius_px` (>= 1) under `sun_azimuth_deg`: CV_32F,
// odd size 2 ceil(1.6 R) + 1, centre at the middle pixel; -(d . s) / R inside the disc (edge
// anti-aliased over one pixel), 0 outside.
cv::Mat BowlShadingTemplate(double radius_px, double sun_azimuth_deg);

struct ShadingHypothesis {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // [px], sub-pixel peak of the correlation
  double radius = 0.0;       // [px], interpolated between the template radii
  double correlation = 0.0;  // peak normalised cross-correlation in [-1, 1]
  // Peak amplitude of the template (least squares, DN per unit ramp) minus the median over the
  // image, over the robust spread (1.4826 MAD) of that amplitude over the image; 0 where the
  // image has no spread.
  double significance = 0.0;
};

// Local maxima over position and radius of the template correlation at least
// options.min_correlation, for radii in [min_radius_px, max_radius_px], duplicates suppressed as in
// SuppressDuplicateCraters (correlation as confidence). Templates are options.radii_per_octave
// per octave, plus one beyond each end of the range that only interpolates the radius (parabola
// in log radius). A template of radius over 4 px runs on a 2x2-averaged copy of the image (one
// per octave) where its radius is 2-4 px; the centres of those hypotheses come from the
// correlation peak of the full-resolution template within +-2 px (cv::matchTemplate). Input:
// single band, any depth, NaN = nodata (filled with the mean for the correlation; hypotheses
// whose window holds nodata are dropped). Sorted by decreasing correlation.
std::vector<ShadingHypothesis> FindShadingHypotheses(const cv::Mat& image, double sun_azimuth_deg,
                                                     double min_radius_px, double max_radius_px,
                                                     const ShadingTemplateOptions& options = {});

// Template-only craters: the hypotheses that no crater of `found` explains (not a duplicate
// of one by SuppressDuplicateCraters' rule, not inside or on the rim of a larger one), accepted on
// their own evidence (correlation, significance, dipole contrast, rim edges along the sun line; see
// ShadingTemplateOptions). `edges`: DetectImageEdges of `image` (same pixels; empty edges accept
// nothing). The circle is the hypothesis', its centre along the sun line and its radius refitted
// to the sun-line rim edges where each side has 3 (sigmas, residual and EFS NaN); coverage is
// the sun-line coverage times 0.5 (the share of the rim that can show edges), signature the dipole
// contrast, shading_correlation the template correlation, confidence 0.5 x correlation x min(1,
// contrast / (3 x min_dipole_contrast)), partial always true.
std::vector<CraterDetection> AcceptShadingHypotheses(
    const cv::Mat& image, const RimEdges& edges, const std::vector<ShadingHypothesis>& hypotheses,
    const std::vector<CraterDetection>& found, double sun_azimuth_deg,
    const ShadingTemplateOptions& options = {});

}  // namespace areomap
