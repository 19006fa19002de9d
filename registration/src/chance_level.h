// The chance level of an orbital match (internal to MatchOrthoToOrbital): the high-passed NCC
// surface of the template at shifts where the match's own peak does not spread, sampled at full
// resolution, and the high-passed peak it is compared with (peak_significance.h turns the two
// into a false-match probability).
//
// Images: CV_32F orbital pixels, NaN or mask 0 where invalid. Shifts: the template's top-left
// pixel on `fixed` pixel (x, y). "High-passed": less the local mean (high_pass.h). Nothing
// throws for lack of data: too few samples give a SurfaceNull that is not valid().
#pragma once

#include <opencv2/core.hpp>

#include "areomap/registration/masked_ncc.h"
#include "areomap/registration/orbital_image.h"
#include "areomap/registration/orbital_match.h"
#include "areomap/registration/orbital_pyramid.h"
#include "areomap/registration/peak_significance.h"
#include "high_pass.h"

namespace areomap::internal {

// The highest NCC of `hp_t` on `hp_fixed` (both high-passed) at shifts within 1 px of `shift`;
// NaN if none is defined.
double PeakNear(const HighPassedImage& hp_fixed, const MaskedImage& hp_t, cv::Point shift,
                double min_overlap_fraction);

// The template's autocorrelation (masked NCC with itself) over shifts up to the size of a
// surface of `rows` x `cols`, with overlaps down to a quarter of its pixels.
MaskedNccSurface Autocorrelation(const MaskedImage& t, int rows, int cols);

// Whether WindowTilesNull's four tiles, for a template of `templ` size, reach as many pixels as a
// window of `window` size holds: then it is cheaper to high-pass the window whole
// (HighPassedImage).
bool NullReachesAllOf(cv::Size window, cv::Size templ);

// The null of a large search window at full resolution: the surface of `hp_t` over `search`
// (shifts on `hp_fixed`; both high-passed), sampled in its four corner tiles of 48 x 48 shifts
// (the whole window as one tile where it is under two tiles a side), at the shifts where the peak
// at shift `peak` does not spread: farther than `exclusion_px` from it, and where the template's
// coarse autocorrelation (Autocorrelation of `coarse_template`, pyramid unit `unit`, over shifts
// up to `acf_extent`) at the offset is below 0.2.
SurfaceNull WindowTilesNull(const HighPassedImage& hp_fixed, const MaskedImage& hp_t,
                            const ShiftWindow& search, cv::Point peak,
                            const MaskedImage& coarse_template, cv::Size acf_extent, int unit,
                            double exclusion_px, double min_overlap_fraction);

// The null of a small search window (OrbitalMatchOptions::null_windows): the full-resolution
// surface of `t` (template top-left on orbital pixel (x, y)) in windows of side 2 radius + 1
// tiling a ring around the window centred on (cx, cy), every shift of a tile farther than
// `exclusion_px` from every shift of that window; the ring grows until `wanted` tiles fit. Tiles
// off the image (no defined CC) are not counted. Sets m.null_windows, null_reaching (best >=
// m.correlation) and null_highest, and returns the statistics of the tiles' pixels.
SurfaceNull NullWindowTest(const OrbitalImage& orbital, const MaskedImage& t, int cx, int cy,
                           int radius, double exclusion_px, int wanted, double min_overlap_fraction,
                           OrbitalMatch& m);

}  // namespace areomap::internal
