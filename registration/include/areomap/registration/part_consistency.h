// Does every part of a template agree that it fits where the whole template does?
//
// A correlation peak can stand far above chance and still be the wrong place: a rover
// orthophoto that shows little but one crater wall fits another crater's wall a few metres off.
// Such a structured look-alike is not chance, so the false-match probability
// (peak_significance.h) does not refuse it. At the right place every part of the template fits
// there too; at a look-alike only the parts that show the shared feature fit, each at a shift of
// its own, and the others fit nowhere in particular.
//
// Test: the template's bounding box is cut into 2 x 2 quadrants. Each quadrant holding at least
// kMinPartShare of the template's valid pixels is correlated alone (masked NCC of the high-passed
// template against the high-passed image, internal/high_pass.h) over the shifts within `radius`
// of the match. Its chance level (mean, spread) comes from its surface at shifts farther than
// radius / 2 from both the match and its own best shift. A quadrant contradicts the match when
//   - its best shift lies more than kPartAgreementPx from the match (on a true match a part may
//     sit a pixel or two off: parallax, resampling, a broad cross-modal peak),
//   - its peak stands clear of its chance level, z_part = (peak - mean) / spread >= kMinPartZ
//     (a part without texture has a best shift anywhere, which says nothing),
//   - and its peak exceeds its NCC at the match by at least kMinContradiction spreads.
// The thresholds separate the true matches of the evaluation set (eval/) from the generated
// look-alikes of tests/registration/orbital_statistics_test.cc: docs/benchmarks.md,
// "Registration decision"; figures in docs/notes/benchmarks-history.md.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/registration/orbital_pyramid.h"

namespace areomap {

inline constexpr double kMinPartShare = 0.1;
inline constexpr double kPartAgreementPx = 2.0;
inline constexpr double kMinPartZ = 5.0;
inline constexpr double kMinContradiction = 2.5;

// One quadrant of a template correlated alone around a match.
struct PartFit {
  std::string name;     // "top-left", "top-right", "bottom-left" or "bottom-right".
  cv::Rect region;      // Template pixels.
  int pixels = 0;       // Valid template pixels in it.
  bool tested = false;  // Enough pixels, a defined surface and chance level.
  cv::Point offset_px;  // Its best shift minus the match's [px].
  double peak = std::numeric_limits<double>::quiet_NaN();      // NCC at its best shift.
  double at_match = std::numeric_limits<double>::quiet_NaN();  // NCC at the match.
  double null_mean = std::numeric_limits<double>::quiet_NaN();
  double null_stddev = std::numeric_limits<double>::quiet_NaN();

  double z() const { return (peak - null_mean) / null_stddev; }
  // (peak - at_match) / null_stddev: how much better the part fits at its own best shift.
  double contradiction() const { return (peak - at_match) / null_stddev; }
  // Its best shift is more than kPartAgreementPx off and clear of chance (z() >= kMinPartZ).
  bool fits_elsewhere() const;
  bool contradicts() const { return fits_elsewhere() && contradiction() >= kMinContradiction; }
};

struct PartConsistency {
  std::vector<PartFit> parts;  // The four quadrants (tested or not).
  int worst = -1;  // The contradicting part with the largest contradiction, -1 when none.

  bool consistent() const { return worst < 0; }
  int tested() const;
  // The largest contradiction() of the parts that fit elsewhere; 0 when none does.
  double largest_contradiction() const;
  // Why the match is refused ("" when consistent).
  std::string Describe() const;
};

// The quadrants of `hp_template` correlated alone over the shifts of `hp_template` on `hp_fixed`
// within `radius` [px] of `match_shift` (top-left of the template on `hp_fixed` [px]). Both
// images high-passed (less their local mean), CV_32F, NaN or masked where invalid. Parts whose
// surface has no defined score at the match or too few chance samples are not tested; nothing
// throws for degenerate input (a template without valid pixels, shifts off the image: four
// untested parts).
PartConsistency CheckPartConsistency(const MaskedImage& hp_fixed, const MaskedImage& hp_template,
                                     cv::Point match_shift, int radius,
                                     double min_overlap_fraction);

}  // namespace areomap
