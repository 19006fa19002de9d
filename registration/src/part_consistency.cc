#include "areomap/registration/part_consistency.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include <tbb/parallel_for.h>

#include "areomap/registration/masked_ncc.h"

namespace areomap {
namespace {

// Too few chance samples give no spread worth dividing by.
constexpr int kMinNullSamples = 16;

cv::Mat ValidMask(const MaskedImage& t) {
  cv::Mat valid(t.image.size(), CV_8U, cv::Scalar(0));
  for (int r = 0; r < t.image.rows; ++r) {
    for (int c = 0; c < t.image.cols; ++c) {
      const bool ok =
          std::isfinite(t.image.at<float>(r, c)) && (t.mask.empty() || t.mask.at<uchar>(r, c) != 0);
      if (ok) valid.at<uchar>(r, c) = 255;
    }
  }
  return valid;
}

// Fills `part`'s peak, score at the match and chance level from its surface `s`, whose shift
// (x, y) is at column x - s.shift_x0 and row y - s.shift_y0; `match` on the same shifts.
void MeasurePart(const MaskedNccSurface& s, cv::Point match, int radius, PartFit* part) {
  const cv::Point m(match.x - s.shift_x0, match.y - s.shift_y0);
  if (m.x < 0 || m.y < 0 || m.x >= s.ncc.cols || m.y >= s.ncc.rows) return;
  part->at_match = s.ncc.at<float>(m.y, m.x);
  if (!std::isfinite(part->at_match)) return;
  cv::Point best = m;
  part->peak = part->at_match;
  for (int r = 0; r < s.ncc.rows; ++r) {
    for (int c = 0; c < s.ncc.cols; ++c) {
      const float v = s.ncc.at<float>(r, c);
      if (std::isfinite(v) && v > part->peak) {
        part->peak = v;
        best = cv::Point(c, r);
      }
    }
  }
  part->offset_px = best - m;
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  const double far = radius / 2.0;
  for (int r = 0; r < s.ncc.rows; ++r) {
    for (int c = 0; c < s.ncc.cols; ++c) {
      const float v = s.ncc.at<float>(r, c);
      if (!std::isfinite(v) || std::hypot(c - m.x, r - m.y) <= far ||
          std::hypot(c - best.x, r - best.y) <= far) {
        continue;
      }
      sum += v;
      sum_sq += static_cast<double>(v) * v;
      ++n;
    }
  }
  if (n < kMinNullSamples) return;
  part->null_mean = sum / n;
  part->null_stddev = std::sqrt(std::max(0.0, sum_sq / n - part->null_mean * part->null_mean));
  part->tested = part->null_stddev > 0.0;
}

}  // namespace

bool PartFit::fits_elsewhere() const {
  return tested && std::hypot(offset_px.x, offset_px.y) > kPartAgreementPx && z() >= kMinPartZ;
}

double PartConsistency::largest_contradiction() const {
  double largest = 0.0;
  for (const PartFit& p : parts) {
    if (p.fits_elsewhere()) largest = std::max(largest, p.contradiction());
  }
  return largest;
}

int PartConsistency::tested() const {
  int n = 0;
  for (const PartFit& p : parts) n += p.tested;
  return n;
}

std::string PartConsistency::Describe() const {
  if (worst < 0) return "";
  const PartFit& p = parts[worst];
  std::ostringstream out;
  out.precision(3);
  out << "the template's " << p.name << " quadrant fits best "
      << std::hypot(p.offset_px.x, p.offset_px.y) << " px from the match (NCC " << p.peak
      << " there, " << p.at_match << " at the match: " << p.contradiction()
      << " of its chance spread; parts of the template fit elsewhere, a look-alike, not its "
         "place)";
  return out.str();
}

PartConsistency CheckPartConsistency(const MaskedImage& hp_fixed, const MaskedImage& hp_template,
                                     cv::Point match_shift, int radius,
                                     double min_overlap_fraction) {
  PartConsistency out;
  const cv::Size size = hp_template.image.size();
  const int half_w = size.width / 2, half_h = size.height / 2;
  const char* names[4] = {"top-left", "top-right", "bottom-left", "bottom-right"};
  for (int k = 0; k < 4; ++k) {
    PartFit part;
    part.name = names[k];
    part.region =
        cv::Rect(k % 2 ? half_w : 0, k / 2 ? half_h : 0, k % 2 ? size.width - half_w : half_w,
                 k / 2 ? size.height - half_h : half_h);
    out.parts.push_back(part);
  }
  if (size.area() == 0 || radius < 1) return out;
  const cv::Mat valid = ValidMask(hp_template);
  const int total = cv::countNonZero(valid);
  const ShiftWindow shifts = ShiftWindow::Around(match_shift.x, match_shift.y, radius);
  // Each quadrant is correlated as a template of its own: at template shift s its top-left
  // pixel lies at s + region.tl(), so its shifts are the template's moved by that corner.
  tbb::parallel_for(0, static_cast<int>(out.parts.size()), [&](int k) {
    PartFit& part = out.parts[k];
    const cv::Mat mask = valid(part.region);
    part.pixels = cv::countNonZero(mask);
    if (part.pixels < kMinPartShare * total || part.pixels < 2) return;
    const cv::Point corner = part.region.tl();
    MaskedNccOptions options;
    options.min_overlap_fraction = min_overlap_fraction;
    // A part's z-score and contradiction (thresholds 5 and 2.5 spreads) do not need the surface
    // to better than ~1e-4: single-precision transforms, about 1.5x faster.
    options.fft_precision = FftPrecision::kSingle;
    options.search_window =
        ShiftWindow{shifts.min_shift_x + corner.x, shifts.max_shift_x + corner.x,
                    shifts.min_shift_y + corner.y, shifts.max_shift_y + corner.y};
    const MaskedNccSurface s =
        MaskedNcc(hp_fixed.image, hp_fixed.mask, hp_template.image(part.region), mask, options);
    MeasurePart(s, match_shift + corner, radius, &part);
  });
  for (int k = 0; k < static_cast<int>(out.parts.size()); ++k) {
    const PartFit& p = out.parts[k];
    if (p.contradicts() &&
        (out.worst < 0 || p.contradiction() > out.parts[out.worst].contradiction())) {
      out.worst = k;
    }
  }
  return out;
}

}  // namespace areomap
