#include "areomap/crater/shading_hypotheses.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>

#include <tbb/parallel_for.h>
#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/crater_detector.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/numbers.h"
#include "bilinear_sample.h"

namespace areomap {
namespace {

// Template window half-width over the radius: room for the flat plain around the bowl.
constexpr double kWindowHalfWidth = 1.6;
// Template radii within one image copy [copy px]: up to 4 (from 2 on the averaged copies), larger
// ones on the next 2x2-averaged copy: 4 px resolve the ramp of a bowl, and each copy costs 1/4.
constexpr double kMaxCopyRadius = 4.0;
constexpr int kCoverageBins = 36;

// Unit vector towards the sun in pixel coordinates (x right, y down), azimuth clockwise from up.
Eigen::Vector2d SunDirection(double azimuth_deg) {
  const double az = azimuth_deg * std::numbers::pi / 180.0;
  return {std::sin(az), -std::cos(az)};
}

// One template radius: its correlation map on one image copy.
struct Scale {
  double radius = 0.0;  // [full-resolution px]
  int copy = 0;         // index of the image copy (2^copy full px per copy px)
  int half = 0;         // template half size [copy px]
  // CV_32F; element (r, c): template centre at copy pixel (c + half, r + half).
  cv::Mat correlation;
  // Least-squares amplitude of the template in each window [DN per unit of the ramp], and its
  // median and robust spread (1.4826 MAD) over the map.
  cv::Mat amplitude;
  double amplitude_median = 0.0;
  double amplitude_spread = 0.0;
};

// Correlation of `scale` at full-resolution point p (bilinear), NaN outside the map.
double CorrelationAt(const Scale& scale, const Eigen::Vector2d& p) {
  const double f = std::ldexp(1.0, scale.copy);
  // GDAL coordinate in the copy -> index of the map (template centre pixel centres at +0.5).
  return internal::SampleBilinearIndex(scale.correlation, p.x() / f - 0.5 - scale.half,
                                       p.y() / f - 0.5 - scale.half);
}

// Vertex offset of the parabola through (-1, a), (0, b), (1, c), within [-0.5, 0.5].
double ParabolaPeak(double a, double b, double c) {
  const double denominator = a - 2.0 * b + c;
  if (!(denominator < 0.0)) return 0.0;
  return std::clamp(0.5 * (a - c) / denominator, -0.5, 0.5);
}

// Local maxima of one map at least `threshold`, as hypotheses in full-resolution pixels.
std::vector<ShadingHypothesis> LocalMaxima(const Scale& scale, double threshold,
                                           const cv::Mat& nodata_count) {
  const cv::Mat& m = scale.correlation;
  const double copy_radius = scale.radius / std::ldexp(1.0, scale.copy);
  const int reach = std::max(1, static_cast<int>(std::lround(0.5 * copy_radius)));
  cv::Mat dilated;
  cv::dilate(m, dilated, cv::getStructuringElement(cv::MORPH_RECT, {2 * reach + 1, 2 * reach + 1}));
  const double f = std::ldexp(1.0, scale.copy);
  std::vector<ShadingHypothesis> out;
  for (int r = 1; r + 1 < m.rows; ++r) {
    const float* row = m.ptr<float>(r);
    const float* peak = dilated.ptr<float>(r);
    for (int c = 1; c + 1 < m.cols; ++c) {
      if (row[c] < threshold || row[c] < peak[c]) continue;
      if (!nodata_count.empty() && nodata_count.at<float>(r + scale.half, c + scale.half) > 0.0f) {
        continue;  // the window touches a nodata hole
      }
      const double dx = ParabolaPeak(row[c - 1], row[c], row[c + 1]);
      const double dy = ParabolaPeak(m.at<float>(r - 1, c), row[c], m.at<float>(r + 1, c));
      ShadingHypothesis h;
      h.center = f * Eigen::Vector2d(c + scale.half + 0.5 + dx, r + scale.half + 0.5 + dy);
      h.radius = scale.radius;
      h.correlation = row[c];
      h.significance =
          scale.amplitude_spread > 0.0
              ? (scale.amplitude.at<float>(r, c) - scale.amplitude_median) / scale.amplitude_spread
              : 0.0;
      out.push_back(h);
    }
  }
  return out;
}

// Dipole contrast of a hypothesis: least-squares fit of brightness = a + b w over the interior
// (rho <= 0.9, w = -(d . s) / R), 2 b (far rim minus sunward rim) over the standard deviation of
// the annulus 1.25-1.75 R. NaN where nodata or no texture leaves it undefined.
double DipoleContrast(const cv::Mat& image, const ShadingHypothesis& h,
                      const Eigen::Vector2d& sun) {
  const double step = std::max(0.5, h.radius / 10.0);
  const double reach = 1.75 * h.radius;
  double sw = 0, sv = 0, sww = 0, swv = 0, n_in = 0;
  double so = 0, soo = 0, n_out = 0;
  for (double dy = -reach; dy <= reach; dy += step) {
    for (double dx = -reach; dx <= reach; dx += step) {
      const double rho = std::hypot(dx, dy) / h.radius;
      if (rho > 0.9 && (rho < 1.25 || rho > 1.75)) continue;
      const double v = internal::SampleBilinear(image, h.center.x() + dx, h.center.y() + dy);
      if (!std::isfinite(v)) return kNaN;
      if (rho <= 0.9) {
        const double w = -(dx * sun.x() + dy * sun.y()) / h.radius;
        sw += w;
        sv += v;
        sww += w * w;
        swv += w * v;
        ++n_in;
      } else {
        so += v;
        soo += v * v;
        ++n_out;
      }
    }
  }
  if (n_in < 8 || n_out < 8) return kNaN;
  const double var_w = sww / n_in - (sw / n_in) * (sw / n_in);
  const double slope = (swv / n_in - (sw / n_in) * (sv / n_in)) / var_w;
  const double std_out = std::sqrt(std::max(0.0, soo / n_out - (so / n_out) * (so / n_out)));
  if (!(std_out > 0.0) || !(var_w > 0.0)) return kNaN;
  return 2.0 * slope / std_out;
}

// The hypothesis' centre from the correlation peak at full resolution (cv::matchTemplate over
// +-2 px around it): hypotheses of radius over kMaxCopyRadius come from a 2x2-averaged copy.
ShadingHypothesis RefinedAtFullResolution(const cv::Mat& image, ShadingHypothesis h,
                                          double sun_azimuth_deg) {
  if (h.radius <= kMaxCopyRadius * 1.0001) return h;  // found at full resolution already
  const cv::Mat t = BowlShadingTemplate(h.radius, sun_azimuth_deg);
  const int half = t.rows / 2, margin = 2;
  const int col = static_cast<int>(std::floor(h.center.x()));
  const int row = static_cast<int>(std::floor(h.center.y()));
  const cv::Rect roi(col - half - margin, row - half - margin, t.cols + 2 * margin,
                     t.rows + 2 * margin);
  if ((roi & cv::Rect(0, 0, image.cols, image.rows)) != roi) return h;
  const cv::Mat window = image(roi);
  if (!cv::checkRange(window)) return h;  // nodata
  cv::Mat correlation;
  cv::matchTemplate(window, t, correlation, cv::TM_CCOEFF_NORMED);
  cv::Point peak;
  cv::minMaxLoc(correlation, nullptr, nullptr, nullptr, &peak);
  if (peak.x < 1 || peak.y < 1 || peak.x > 2 * margin - 1 || peak.y > 2 * margin - 1) return h;
  const auto at = [&](int r, int c) { return static_cast<double>(correlation.at<float>(r, c)); };
  const double dx =
      ParabolaPeak(at(peak.y, peak.x - 1), at(peak.y, peak.x), at(peak.y, peak.x + 1));
  const double dy =
      ParabolaPeak(at(peak.y - 1, peak.x), at(peak.y, peak.x), at(peak.y + 1, peak.x));
  h.center = {col + peak.x - margin + 0.5 + dx, row + peak.y - margin + 0.5 + dy};
  return h;
}

// Rim edges of bowl polarity near the circle along the sun line.
struct SunLineRim {
  double coverage = 0.0;  // share of the 16 sectors (of 36) centred within 40 degrees of the line
  // Circle from the edges: both rim crossings of the sun line fix the centre along the line and
  // the radius (least squares of the radial residuals e = dR + shift (u . s) over the edges,
  // with the centre across the line kept); unset without 3 edges on each side.
  std::optional<Eigen::Vector2d> center;
  double radius = 0.0;
  Eigen::Vector2d hypothesis_center = Eigen::Vector2d::Zero();  // the circle it started from
};

SunLineRim FindSunLineRim(const RimEdges& edges, const ShadingHypothesis& h,
                          const Eigen::Vector2d& sun) {
  SunLineRim out;
  out.hypothesis_center = h.center;
  if (edges.points.empty() || edges.rows <= 0) return out;
  Eigen::Matrix2d normal_matrix = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  int sunward = 0, far = 0;
  const double tolerance = std::max(1.5, 0.15 * h.radius);
  const double reach = h.radius + tolerance + 1.0;
  const int c0 = std::max(0, static_cast<int>(std::floor(h.center.x() - reach)));
  const int c1 = std::min(edges.cols - 1, static_cast<int>(std::ceil(h.center.x() + reach)));
  const int r0 = std::max(0, static_cast<int>(std::floor(h.center.y() - reach)));
  const int r1 = std::min(edges.rows - 1, static_cast<int>(std::ceil(h.center.y() + reach)));
  std::array<bool, kCoverageBins> hit{};
  for (int r = r0; r <= r1; ++r) {
    const int row_end = edges.row_start[static_cast<size_t>(r) + 1];
    for (int i = edges.FirstInRow(r, c0); i < row_end && edges.column[static_cast<size_t>(i)] <= c1;
         ++i) {
      const RimEdgePoint& p = edges.points[static_cast<size_t>(i)];
      const Eigen::Vector2d d = Eigen::Vector2d(p.x, p.y) - h.center;
      const double dist = d.norm();
      if (dist <= 0.0 || std::abs(dist - h.radius) > tolerance) continue;
      const Eigen::Vector2d u = d / dist, n(p.nx, p.ny);
      if (std::abs(n.dot(u)) < 0.8 || n.dot(sun) <= 0.0) continue;  // radial, towards the sun
      // 36 sectors of polar angle from the sun direction; the 16 whose centres lie within 40
      // degrees of the sun line count.
      const double t = std::atan2(u.x() * sun.y() - u.y() * sun.x(), u.dot(sun));
      const int bin =
          std::clamp(static_cast<int>(std::floor((t + std::numbers::pi) / (2.0 * std::numbers::pi) *
                                                 kCoverageBins)),
                     0, kCoverageBins - 1);
      const double centre = (bin + 0.5) / kCoverageBins * 2.0 * std::numbers::pi - std::numbers::pi;
      if (std::abs(std::cos(centre)) < std::cos(std::numbers::pi / 4.0) + 1e-6)
        continue;  // off the sun line
      hit[static_cast<size_t>(bin)] = true;
      const Eigen::Vector2d row(1.0, u.dot(sun));
      normal_matrix += row * row.transpose();
      rhs += row * (dist - h.radius);
      (row.y() > 0.0 ? sunward : far) += 1;
    }
  }
  out.coverage = static_cast<double>(std::count(hit.begin(), hit.end(), true)) / 16.0;
  if (sunward >= 3 && far >= 3) {
    const Eigen::Vector2d solution = normal_matrix.ldlt().solve(rhs);  // (dR, shift)
    if (solution.allFinite() && std::abs(solution.x()) < 0.2 * h.radius &&
        std::abs(solution.y()) < 0.3 * h.radius) {
      out.center = h.center + solution.y() * sun;
      out.radius = h.radius + solution.x();
    }
  }
  return out;
}

// The template radii: radii_per_octave per octave over [min_radius_px, max_radius_px], with one
// beyond each end, each on the coarsest image copy where it stays within kMaxCopyRadius.
std::vector<Scale> TemplateScales(double min_radius_px, double max_radius_px, double step) {
  std::vector<Scale> scales;
  // One template beyond each end of the range, so that the radius interpolates there too.
  for (double r = std::max(1.0, min_radius_px / step); r <= max_radius_px * step * 1.0001;
       r *= step) {
    int copy = 0;
    while (r / std::ldexp(1.0, copy) > kMaxCopyRadius * 1.0001) ++copy;
    Scale s;
    s.radius = r;
    s.copy = copy;
    s.half = static_cast<int>(std::ceil(kWindowHalfWidth * r / std::ldexp(1.0, copy)));
    scales.push_back(s);
  }
  // The template below the range only interpolates the radius: not worth a finer copy.
  if (scales.size() > 1 && scales[0].radius < min_radius_px / std::sqrt(step) &&
      scales[0].copy < scales[1].copy) {
    scales.erase(scales.begin());
  }
  return scales;
}

// The image copies the templates correlate with: full resolution, then 2x2 averages (the GDAL
// grid scales exactly by 2). Those a template uses are filled (nodata by the mean) and have
// zero mean, with their squares and, where they had nodata, the count of nodata pixels in each
// window of the largest template.
struct ImageCopies {
  std::vector<cv::Mat> copies, nodata, squares;
};

// Nodata of `copy` filled with the mean of the rest, `count` the nodata pixels in each window of
// 2 half_max + 1 px (left empty without nodata); then the copy's mean subtracted.
void PrepareCopy(cv::Mat& copy, cv::Mat& count, int half_max) {
  cv::Mat mask = NanMask(copy);
  if (cv::countNonZero(mask) > 0) {
    const double fill = cv::mean(copy, ~mask)[0];
    copy.setTo(std::isfinite(fill) ? fill : 0.0, mask);
    mask.convertTo(count, CV_32F, 1.0 / 255.0);
    cv::boxFilter(count, count, -1, {2 * half_max + 1, 2 * half_max + 1}, {-1, -1}, false);
  }
  // Zero mean: the window sums of squares below keep their float precision.
  copy -= cv::mean(copy)[0];
}

ImageCopies MakeImageCopies(const cv::Mat& image, const std::vector<Scale>& scales) {
  ImageCopies out;
  std::vector<cv::Mat>& copies = out.copies;
  copies.resize(1);
  out.nodata.resize(1);
  image.convertTo(copies[0], CV_32F);
  const int copies_needed = scales.empty() ? 0 : scales.back().copy + 1;
  // Unfilled copies first (2x2 averages keep NaN where any input is nodata), then filled.
  for (int k = 1; k < copies_needed; ++k) {
    const cv::Mat& src = copies.back();
    if (src.cols < 4 || src.rows < 4) break;
    cv::Mat next;
    cv::resize(src(cv::Rect(0, 0, src.cols / 2 * 2, src.rows / 2 * 2)), next,
               cv::Size(src.cols / 2, src.rows / 2), 0, 0, cv::INTER_AREA);
    copies.push_back(next);
  }
  out.nodata.resize(copies.size());
  const int half_max = static_cast<int>(std::ceil(kWindowHalfWidth * kMaxCopyRadius)) + 1;
  out.squares.resize(copies.size());
  for (size_t k = 0; k < copies.size(); ++k) {
    if (std::none_of(scales.begin(), scales.end(),
                     [&](const Scale& sc) { return sc.copy == static_cast<int>(k); })) {
      continue;  // only a step of the pyramid
    }
    PrepareCopy(copies[k], out.nodata[k], half_max);
    out.squares[k] = copies[k].mul(copies[k]);
  }
  return out;
}

// The correlation and amplitude maps of `s` on its copy, and the amplitude's robust statistics.
void CorrelateScale(const ImageCopies& copies, double sun_azimuth_deg, Scale& s) {
  const cv::Mat t = BowlShadingTemplate(s.radius / std::ldexp(1.0, s.copy), sun_azimuth_deg);
  const cv::Mat& image_copy = copies.copies[s.copy];
  // Normalised cross-correlation (as cv::matchTemplate's TM_CCOEFF_NORMED) from one filter2D
  // (OpenCV's filter2D correlates) and box sums over the template's window: T has zero mean,
  // so sum T I = sum T (I - window mean). Maps keep matchTemplate's layout (valid windows).
  const cv::Size window(t.cols, t.rows);
  cv::Mat response, sum, sum_sq;
  cv::filter2D(image_copy, response, CV_32F, t);
  cv::boxFilter(image_copy, sum, CV_32F, window, {-1, -1}, false);
  cv::boxFilter(copies.squares[s.copy], sum_sq, CV_32F, window, {-1, -1}, false);
  const cv::Rect valid(s.half, s.half, image_copy.cols - 2 * s.half, image_copy.rows - 2 * s.half);
  const double t_norm = cv::norm(t);
  cv::Mat spread = sum_sq(valid) - sum(valid).mul(sum(valid)) / window.area();
  // A window flatter than 1e-3 DN RMS has no correlation.
  const cv::Mat flat = spread < 1e-6 * window.area();
  cv::max(spread, 1e-6 * window.area(), spread);
  cv::sqrt(spread, spread);
  cv::divide(response(valid), spread, s.correlation, 1.0 / t_norm);
  s.correlation.setTo(0.0, flat);
  cv::min(cv::max(s.correlation, -1.0), 1.0, s.correlation);
  // Least-squares amplitude of the template: sum T I / sum T^2.
  s.amplitude = response(valid) / (t_norm * t_norm);
  // Robust statistics of the amplitude over the map (every 4th row and column).
  std::vector<float> values;
  for (int r = 0; r < s.amplitude.rows; r += 4) {
    for (int c = 0; c < s.amplitude.cols; c += 4) values.push_back(s.amplitude.at<float>(r, c));
  }
  if (values.size() < 16) return;
  const auto median = [](std::vector<float>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return static_cast<double>(v[v.size() / 2]);
  };
  s.amplitude_median = median(values);
  for (float& v : values) v = std::abs(v - static_cast<float>(s.amplitude_median));
  s.amplitude_spread = 1.4826 * median(values);
}

// The hypotheses of scale `i` (none for the templates beyond the range): its local maxima that
// are also maxima over the radius, the radius interpolated between the templates.
std::vector<ShadingHypothesis> ScaleHypotheses(const std::vector<Scale>& scales, size_t i,
                                               const ImageCopies& copies, double min_radius_px,
                                               double max_radius_px, double step,
                                               double min_correlation) {
  if (scales[i].radius < min_radius_px / std::sqrt(step) ||
      scales[i].radius > max_radius_px * std::sqrt(step)) {
    return {};  // the templates beyond the range only interpolate the radius
  }
  std::vector<ShadingHypothesis> found =
      LocalMaxima(scales[i], min_correlation, copies.nodata[scales[i].copy]);
  // Maxima over the radius too (the neighbouring templates correlate less at the same
  // point); the radius between the templates from the parabola in log radius through them.
  std::erase_if(found, [&](ShadingHypothesis& h) {
    const double below = i > 0 ? CorrelationAt(scales[i - 1], h.center) : kNaN;
    const double above = i + 1 < scales.size() ? CorrelationAt(scales[i + 1], h.center) : kNaN;
    if (below > h.correlation || above > h.correlation) return true;
    if (std::isfinite(below) && std::isfinite(above)) {
      h.radius *= std::pow(step, ParabolaPeak(below, h.correlation, above));
    }
    return false;
  });
  return found;
}

// Duplicates over neighbouring positions and radii suppressed: the detector's rule, correlation
// as confidence.
std::vector<ShadingHypothesis> DistinctHypotheses(
    const std::vector<std::vector<ShadingHypothesis>>& per_scale) {
  std::vector<CraterDetection> as_craters;
  for (const auto& list : per_scale) {
    for (const ShadingHypothesis& h : list) {
      CraterDetection d;
      d.ellipse = {h.center, h.radius, h.radius, 0.0};
      d.confidence = h.correlation;
      d.shading_correlation = h.correlation;
      d.signature = h.significance;
      as_craters.push_back(d);
    }
  }
  std::vector<ShadingHypothesis> out;
  for (const CraterDetection& d : SuppressDuplicateCraters(std::move(as_craters))) {
    out.push_back({d.ellipse.center, d.ellipse.semi_major, d.shading_correlation, d.signature});
  }
  return out;
}

}  // namespace

void ShadingTemplateOptions::Check() const {
  RequireOption(radii_per_octave >= 1 && radii_per_octave <= 16,
                "ShadingTemplateOptions.radii_per_octave", "in [1, 16]");
  RequireOption(min_correlation > 0.0 && min_correlation < 1.0,
                "ShadingTemplateOptions.min_correlation", "in (0, 1)");
  RequireOption(std::isfinite(min_significance), "ShadingTemplateOptions.min_significance",
                "finite");
  RequireOption(std::isfinite(min_dipole_contrast) && min_dipole_contrast >= 0.0,
                "ShadingTemplateOptions.min_dipole_contrast", ">= 0");
  RequireOption(min_sun_line_coverage >= 0.0 && min_sun_line_coverage <= 1.0,
                "ShadingTemplateOptions.min_sun_line_coverage", "in [0, 1]");
}

cv::Mat BowlShadingTemplate(double radius_px, double sun_azimuth_deg) {
  RequireOption(std::isfinite(radius_px) && radius_px >= 1.0, "BowlShadingTemplate radius_px",
                ">= 1 px");
  RequireOption(std::isfinite(sun_azimuth_deg), "BowlShadingTemplate sun_azimuth_deg", "finite");
  const Eigen::Vector2d sun = SunDirection(sun_azimuth_deg);
  const int half = static_cast<int>(std::ceil(kWindowHalfWidth * radius_px));
  cv::Mat t(2 * half + 1, 2 * half + 1, CV_32F);
  for (int r = 0; r < t.rows; ++r) {
    for (int c = 0; c < t.cols; ++c) {
      const double dx = c - half, dy = r - half;
      const double inside = std::clamp(radius_px + 0.5 - std::hypot(dx, dy), 0.0, 1.0);
      t.at<float>(r, c) = static_cast<float>(-inside * (dx * sun.x() + dy * sun.y()) / radius_px);
    }
  }
  t -= cv::mean(t)[0];
  return t;
}

std::vector<ShadingHypothesis> FindShadingHypotheses(const cv::Mat& image, double sun_azimuth_deg,
                                                     double min_radius_px, double max_radius_px,
                                                     const ShadingTemplateOptions& options) {
  options.Check();
  RequireOption(std::isfinite(min_radius_px) && min_radius_px >= 1.0,
                "FindShadingHypotheses min_radius_px", ">= 1 px");
  RequireOption(std::isfinite(sun_azimuth_deg), "FindShadingHypotheses sun_azimuth_deg", "finite");
  if (image.channels() != 1) throw Error("shading hypotheses: expected a single-band image");
  if (image.empty() || !(max_radius_px >= min_radius_px)) return {};
  const double step = std::exp2(1.0 / options.radii_per_octave);
  std::vector<Scale> scales = TemplateScales(min_radius_px, max_radius_px, step);
  const ImageCopies copies = MakeImageCopies(image, scales);
  std::erase_if(scales, [&](const Scale& s) {
    const cv::Mat& c =
        copies.copies.size() > static_cast<size_t>(s.copy) ? copies.copies[s.copy] : cv::Mat();
    return c.empty() || c.cols < 2 * s.half + 3 || c.rows < 2 * s.half + 3;
  });
  tbb::parallel_for(size_t{0}, scales.size(),
                    [&](size_t i) { CorrelateScale(copies, sun_azimuth_deg, scales[i]); });
  std::vector<std::vector<ShadingHypothesis>> per_scale(scales.size());
  tbb::parallel_for(size_t{0}, scales.size(), [&](size_t i) {
    per_scale[i] = ScaleHypotheses(scales, i, copies, min_radius_px, max_radius_px, step,
                                   options.min_correlation);
  });
  std::vector<ShadingHypothesis> out = DistinctHypotheses(per_scale);
  // Hypotheses from the averaged copies: centre from the full-resolution peak.
  cv::Mat full;
  image.convertTo(full, CV_32F);
  tbb::parallel_for(size_t{0}, out.size(), [&](size_t i) {
    out[i] = RefinedAtFullResolution(full, out[i], sun_azimuth_deg);
  });
  return out;
}

namespace {

// True when `a` and `b` are one crater by SuppressDuplicateCraters' rule.
bool SameCrater(const CraterDetection& a, const CraterDetection& b) {
  CraterDetection first = a, second = b;
  first.confidence = 1.0;
  second.confidence = 0.0;
  return SuppressDuplicateCraters({first, second}).size() == 1;
}

}  // namespace

std::vector<CraterDetection> AcceptShadingHypotheses(
    const cv::Mat& image, const RimEdges& edges, const std::vector<ShadingHypothesis>& hypotheses,
    const std::vector<CraterDetection>& found, double sun_azimuth_deg,
    const ShadingTemplateOptions& options) {
  options.Check();
  if (image.channels() != 1) throw Error("shading hypotheses: expected a single-band image");
  cv::Mat f;
  image.convertTo(f, CV_32F);
  const Eigen::Vector2d sun = SunDirection(sun_azimuth_deg);
  std::vector<std::optional<CraterDetection>> accepted(hypotheses.size());
  tbb::parallel_for(size_t{0}, hypotheses.size(), [&](size_t i) {
    const ShadingHypothesis& h = hypotheses[i];
    if (h.correlation < options.min_correlation || h.significance < options.min_significance) {
      return;
    }
    CraterDetection d;
    d.ellipse = {h.center, h.radius, h.radius, 0.0};
    for (const CraterDetection& k : found) {
      const double rk = k.ellipse.MeanRadius(), distance = (k.ellipse.center - h.center).norm();
      if (distance > rk + h.radius) continue;
      if (SameCrater(k, d)) return;
      // Inside or on the rim of a larger crater: its walls' shading explains the dipole.
      if (rk > h.radius && distance < rk + 0.5 * h.radius) return;
    }
    const double contrast = DipoleContrast(f, h, sun);
    if (!(contrast >= options.min_dipole_contrast)) return;
    const SunLineRim rim = FindSunLineRim(edges, h, sun);
    if (rim.coverage < options.min_sun_line_coverage) return;
    d.ellipse = {rim.center ? *rim.center : rim.hypothesis_center,
                 rim.center ? rim.radius : h.radius, rim.center ? rim.radius : h.radius, 0.0};
    d.center_x_sigma = d.center_y_sigma = d.semi_major_sigma = d.semi_minor_sigma = d.angle_sigma =
        d.rms_residual = d.efs = kNaN;
    d.coverage = 0.5 * rim.coverage;
    d.signature = contrast;
    d.shading_correlation = h.correlation;
    d.confidence = 0.5 * h.correlation *
                   std::min(1.0, contrast / std::max(1e-9, 3.0 * options.min_dipole_contrast));
    d.partial = true;
    accepted[i] = d;
  });
  std::vector<CraterDetection> out;
  for (const auto& d : accepted) {
    if (d) out.push_back(*d);
  }
  // Overlapping hypotheses accepted together: the more confident one stays.
  return SuppressDuplicateCraters(std::move(out));
}

}  // namespace areomap
