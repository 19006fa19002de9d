#include "areomap/registration/edge_verify.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <sstream>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/numbers.h"

namespace areomap {
namespace {

// Canny's high threshold: this percentile of the gradient magnitude (the low one is half).
constexpr double kHighPercentile = 0.9;

double Median(std::vector<double>& v) {
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The template resampled onto the orbital patch under the match's correction.
cv::Mat RegisteredTemplate(const OrbitalMatch& m) {
  const cv::Mat& patch = m.orbital_patch;
  cv::Mat map_x(patch.size(), CV_32F), map_y(patch.size(), CV_32F);
  for (int r = 0; r < patch.rows; ++r) {
    for (int c = 0; c < patch.cols; ++c) {
      const Eigen::Vector2d t =
          m.OrbitalToTemplate({m.orbital_window.col0 + c + 0.5, m.orbital_window.row0 + r + 0.5});
      map_x.at<float>(r, c) = static_cast<float>(t.x() - 0.5);
      map_y.at<float>(r, c) = static_cast<float>(t.y() - 0.5);
    }
  }
  cv::Mat value(m.templ.image.size(), CV_32F, cv::Scalar(0.0f)), weight;
  m.templ.image.copyTo(value, m.templ.mask);
  m.templ.mask.convertTo(weight, CV_32F, 1.0 / 255.0);
  cv::Mat v, w;
  cv::remap(value, v, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0.0);
  cv::remap(weight, w, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0.0);
  cv::Mat out(patch.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (int r = 0; r < out.rows; ++r) {
    for (int c = 0; c < out.cols; ++c) {
      const float wt = w.at<float>(r, c);
      if (wt >= 0.99f) out.at<float>(r, c) = v.at<float>(r, c) / wt;
    }
  }
  return out;
}

// Canny edges inside `region` of an image with NaN holes: standardized to 8 bits over the
// region, smoothed, thresholds at the kHighPercentile percentile of the gradient magnitude (high)
// and half of it (low).
cv::Mat Edges(const cv::Mat& image, const cv::Mat& region, double sigma) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(image, mean, stddev, region);
  cv::Mat filled(image.size(), CV_32F, cv::Scalar(mean[0]));
  image.copyTo(filled, region);
  cv::Mat bytes;
  filled.convertTo(bytes, CV_8U, 40.0 / std::max(stddev[0], 1e-12),
                   128.0 - 40.0 * mean[0] / std::max(stddev[0], 1e-12));
  if (sigma > 0.0) cv::GaussianBlur(bytes, bytes, cv::Size(), sigma, sigma);
  cv::Mat gx, gy, magnitude;
  cv::Sobel(bytes, gx, CV_32F, 1, 0);
  cv::Sobel(bytes, gy, CV_32F, 0, 1);
  cv::magnitude(gx, gy, magnitude);
  std::vector<float> values;
  for (int r = 0; r < magnitude.rows; ++r) {
    for (int c = 0; c < magnitude.cols; ++c) {
      if (region.at<uchar>(r, c)) values.push_back(magnitude.at<float>(r, c));
    }
  }
  cv::Mat edges(image.size(), CV_8U, cv::Scalar(0));
  if (values.empty()) return edges;
  const auto p90 = values.begin() + static_cast<std::ptrdiff_t>(
                                        kHighPercentile * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), p90, values.end());
  const double high = std::max(1.0, static_cast<double>(*p90));
  cv::Canny(bytes, edges, 0.5 * high, high, 3, true);
  edges &= region;
  return edges;
}

std::vector<Eigen::Vector2d> Points(const cv::Mat& edges, double col0, double row0) {
  std::vector<cv::Point> nz;
  cv::findNonZero(edges, nz);
  std::vector<Eigen::Vector2d> out;
  out.reserve(nz.size());
  for (const cv::Point& p : nz) out.emplace_back(col0 + p.x + 0.5, row0 + p.y + 0.5);
  return out;
}

// The edges of the registered orthophoto and of the orbital patch, in the area both cover.
struct EdgeMaps {
  cv::Mat orbital;                            // CV_8U of the patch, nonzero on an edge point.
  std::vector<Eigen::Vector2d> ortho_points;  // Ortho edge points [orbital px].
  double col0 = 0.0;                          // The patch's top-left orbital pixel.
  double row0 = 0.0;
};

EdgeMaps DetectEdges(const OrbitalMatch& match, const EdgeVerificationOptions& options) {
  const cv::Mat registered = RegisteredTemplate(match);
  cv::Mat region = (registered == registered) & (match.orbital_patch == match.orbital_patch);
  cv::erode(region, region, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(7, 7)));
  const cv::Mat ortho_edges = Edges(registered, region, options.canny_sigma_px);
  EdgeMaps edges;
  edges.orbital = Edges(match.orbital_patch, region, options.canny_sigma_px);
  edges.col0 = match.orbital_window.col0;
  edges.row0 = match.orbital_window.row0;
  edges.ortho_points = Points(ortho_edges, edges.col0, edges.row0);
  return edges;
}

// Whether patch pixel (r, c) lies on the patch and on an orbital edge.
bool IsOrbitalEdge(const cv::Mat& orbital_edges, int r, int c) {
  return r >= 0 && c >= 0 && r < orbital_edges.rows && c < orbital_edges.cols &&
         orbital_edges.at<uchar>(r, c) != 0;
}

// An ortho edge point and its nearest orbital edge point (patch pixel), `d` px apart.
struct Candidate {
  double d;
  int a;
  cv::Point b;
};

// Each ortho edge point's nearest orbital edge point within max_pair_distance_px, closest first.
std::vector<Candidate> NearestOrbitalEdges(const EdgeMaps& edges,
                                           const EdgeVerificationOptions& options) {
  const std::vector<Eigen::Vector2d>& a_points = edges.ortho_points;
  const cv::Mat& orbital_edges = edges.orbital;
  std::vector<Candidate> candidates;
  const int reach = static_cast<int>(std::ceil(options.max_pair_distance_px));
  for (int i = 0; i < static_cast<int>(a_points.size()); ++i) {
    const int c = static_cast<int>(a_points[i].x() - edges.col0),
              r = static_cast<int>(a_points[i].y() - edges.row0);
    Candidate best{std::numeric_limits<double>::infinity(), i, {}};
    for (int dr = -reach; dr <= reach; ++dr) {
      for (int dc = -reach; dc <= reach; ++dc) {
        const int rr = r + dr, cc = c + dc;
        if (rr < 0 || cc < 0 || rr >= orbital_edges.rows || cc >= orbital_edges.cols) continue;
        if (!orbital_edges.at<uchar>(rr, cc)) continue;
        const double d = std::hypot(dr, dc);
        if (d <= options.max_pair_distance_px && d < best.d) best = {d, i, {cc, rr}};
      }
    }
    if (std::isfinite(best.d)) candidates.push_back(best);
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& x, const Candidate& y) { return x.d < y.d; });
  return candidates;
}

// Pairs each ortho edge point with its nearest orbital edge point within the distance limit,
// one-to-one (closest first): out.pairs, pairs_per_group and the paired rates.
void PairEdgePoints(const EdgeMaps& edges, const EdgeVerificationOptions& options,
                    EdgeVerification& out) {
  const std::vector<Candidate> candidates = NearestOrbitalEdges(edges, options);
  cv::Mat taken(edges.orbital.size(), CV_8U, cv::Scalar(0));
  for (const Candidate& k : candidates) {
    if (taken.at<uchar>(k.b)) continue;
    taken.at<uchar>(k.b) = 1;
    EdgePair pair;
    pair.ortho_px = edges.ortho_points[k.a];
    pair.orbital_px = Eigen::Vector2d(edges.col0 + k.b.x + 0.5, edges.row0 + k.b.y + 0.5);
    pair.distance_px = k.d;
    pair.group = k.d == 0.0 ? 0 : std::min(3, static_cast<int>(std::ceil(k.d - 1e-9)));
    ++out.pairs_per_group[pair.group];
    out.pairs.push_back(pair);
  }
  out.ortho_rate = static_cast<double>(out.pairs.size()) / out.ortho_edges;
  out.orbital_rate = static_cast<double>(out.pairs.size()) / out.orbital_edges;
}

// World-view vectors per group (each group's pairs are linked by their image positions): sets
// each compared pair's differences and pattern_match, and out.pattern_pairs.
void CompareWorldViewVectors(const EdgeVerificationOptions& options, EdgeVerification& out) {
  for (int g = 0; g < 4; ++g) {
    std::vector<size_t> members;
    for (size_t k = 0; k < out.pairs.size(); ++k) {
      if (out.pairs[k].group == g) members.push_back(k);
    }
    if (members.size() < 3) continue;
    const size_t stride =
        (members.size() + options.max_wvv_points - 1) / static_cast<size_t>(options.max_wvv_points);
    std::vector<size_t> used;
    for (size_t k = 0; k < members.size(); k += stride) used.push_back(members[k]);
    std::vector<Eigen::Vector2d> a, b;
    for (size_t k : used) {
      a.push_back(out.pairs[k].ortho_px);
      b.push_back(out.pairs[k].orbital_px);
    }
    std::vector<double> dr, dt;
    WorldViewVectorDifferences(a, b, options.wvv_min_radius_px, dr, dt);
    for (size_t k = 0; k < used.size(); ++k) {
      EdgePair& p = out.pairs[used[k]];
      p.wvv_radius_diff_px = dr[k];
      p.wvv_angle_diff_deg = dt[k];
      p.pattern_match =
          dr[k] <= options.wvv_max_radius_diff_px && dt[k] <= options.wvv_max_angle_diff_deg;
      out.pattern_pairs += p.pattern_match ? 1 : 0;
    }
  }
}

// Every (ortho, orbital) edge point pair within fit_radius_px votes for its offset; the peak of
// the votes (3 x 3 centroid) is the shift. This is the exhaustive one-point consensus of all
// candidate correspondences, and unlike nearest pairs it sees an offset larger than the pairing
// distance. std::nullopt when the peak lies on the edge of the votes.
std::optional<Eigen::Vector2d> VotedShift(const EdgeMaps& edges,
                                          const EdgeVerificationOptions& options) {
  const int reach_fit = static_cast<int>(std::ceil(options.fit_radius_px));
  const int n = 2 * reach_fit + 1;
  cv::Mat votes(n, n, CV_64F, cv::Scalar(0.0));
  for (const Eigen::Vector2d& p : edges.ortho_points) {
    const int c = static_cast<int>(p.x() - edges.col0), r = static_cast<int>(p.y() - edges.row0);
    for (int dr = -reach_fit; dr <= reach_fit; ++dr) {
      for (int dc = -reach_fit; dc <= reach_fit; ++dc) {
        if (IsOrbitalEdge(edges.orbital, r + dr, c + dc)) {
          votes.at<double>(dr + reach_fit, dc + reach_fit) += 1;
        }
      }
    }
  }
  cv::Point peak;
  cv::minMaxLoc(votes, nullptr, nullptr, nullptr, &peak);
  if (peak.x == 0 || peak.y == 0 || peak.x == n - 1 || peak.y == n - 1) return std::nullopt;
  double sum = 0.0, sx = 0.0, sy = 0.0;
  for (int dr = -1; dr <= 1; ++dr) {
    for (int dc = -1; dc <= 1; ++dc) {
      const double w = votes.at<double>(peak.y + dr, peak.x + dc);
      sum += w;
      sx += w * (peak.x + dc - reach_fit);
      sy += w * (peak.y + dr - reach_fit);
    }
  }
  return Eigen::Vector2d(sx / sum, sy / sum);
}

// The translation fit: the voted shift, and as inliers the ortho edge points with an orbital
// edge point within the threshold of their shifted position.
void FitTranslation(const EdgeMaps& edges, const EdgeVerificationOptions& options,
                    EdgeVerification& out) {
  const std::optional<Eigen::Vector2d> shift = VotedShift(edges, options);
  if (!shift) return;
  out.shift_px = *shift;
  const int reach_in = static_cast<int>(std::ceil(options.inlier_threshold_px)) + 1;
  double sum_sq = 0.0;
  for (const Eigen::Vector2d& p : edges.ortho_points) {
    const Eigen::Vector2d q = p + out.shift_px;
    const int c = static_cast<int>(std::floor(q.x() - edges.col0));
    const int r = static_cast<int>(std::floor(q.y() - edges.row0));
    double best = std::numeric_limits<double>::infinity();
    for (int dr = -reach_in; dr <= reach_in; ++dr) {
      for (int dc = -reach_in; dc <= reach_in; ++dc) {
        if (!IsOrbitalEdge(edges.orbital, r + dr, c + dc)) continue;
        const Eigen::Vector2d e(edges.col0 + c + dc + 0.5, edges.row0 + r + dr + 0.5);
        best = std::min(best, (e - q).squaredNorm());
      }
    }
    if (best <= options.inlier_threshold_px * options.inlier_threshold_px) {
      ++out.inliers;
      sum_sq += best;
    }
  }
  out.rms_px = out.inliers > 0 ? std::sqrt(sum_sq / out.inliers) : kNaN;
  out.fitted = out.inliers > 0;
  out.consistent = out.fitted && out.shift_px.norm() <= options.max_residual_shift_px &&
                   out.inliers >= options.min_inlier_fraction * out.ortho_edges;
}

// The similarity fit: OpenCV RANSAC on the pattern pairs, about their centroid.
void FitSimilarity(const EdgeVerificationOptions& options, EdgeVerification& out) {
  std::vector<const EdgePair*> fit_set;
  for (const EdgePair& p : out.pairs) {
    if (p.pattern_match) fit_set.push_back(&p);
  }
  if (fit_set.size() < 3) return;
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const EdgePair* p : fit_set) centre += p->ortho_px;
  centre /= static_cast<double>(fit_set.size());
  out.centre_px = centre;
  std::vector<cv::Point2f> src, dst;
  for (const EdgePair* p : fit_set) {
    src.emplace_back(static_cast<float>(p->ortho_px.x() - centre.x()),
                     static_cast<float>(p->ortho_px.y() - centre.y()));
    dst.emplace_back(static_cast<float>(p->orbital_px.x() - centre.x()),
                     static_cast<float>(p->orbital_px.y() - centre.y()));
  }
  cv::setRNGSeed(1);  // Deterministic RANSAC.
  std::vector<uchar> mask;
  const cv::Mat m = cv::estimateAffinePartial2D(src, dst, mask, cv::RANSAC,
                                                options.inlier_threshold_px, 2000, 0.999, 10);
  if (m.empty()) return;
  const double a = m.at<double>(0, 0), b = m.at<double>(1, 0);
  out.scale = std::hypot(a, b);
  out.rotation_rad = std::atan2(-b, a);  // orbital_match.h's sense (CCW on a north-up map).
  out.shift_px = Eigen::Vector2d(m.at<double>(0, 2), m.at<double>(1, 2));
  Eigen::Matrix2d am;
  am << std::cos(out.rotation_rad), std::sin(out.rotation_rad), -std::sin(out.rotation_rad),
      std::cos(out.rotation_rad);
  double sum_sq = 0.0;
  for (size_t k = 0; k < fit_set.size(); ++k) {
    if (!mask[k]) continue;
    ++out.inliers;
    const EdgePair& p = *fit_set[k];
    const Eigen::Vector2d predicted =
        centre + out.shift_px + out.scale * am * (p.ortho_px - centre);
    sum_sq += (p.orbital_px - predicted).squaredNorm();
  }
  out.rms_px = out.inliers > 0 ? std::sqrt(sum_sq / out.inliers) : kNaN;
  out.fitted = out.inliers > 0;
  out.consistent = out.fitted && out.shift_px.norm() <= options.max_residual_shift_px &&
                   out.inliers >= options.min_inlier_fraction * static_cast<double>(fit_set.size());
}

}  // namespace

void EdgeVerificationOptions::Check() const {
  RequireOption(canny_sigma_px >= 0.0, "EdgeVerificationOptions.canny_sigma_px", ">= 0 px");
  RequireOption(max_pair_distance_px > 0.0 && max_pair_distance_px <= 10.0,
                "EdgeVerificationOptions.max_pair_distance_px", "in (0, 10] px");
  RequireOption(max_wvv_points >= 3, "EdgeVerificationOptions.max_wvv_points", ">= 3");
  RequireOption(wvv_min_radius_px >= 0.0, "EdgeVerificationOptions.wvv_min_radius_px", ">= 0");
  RequireOption(wvv_max_radius_diff_px > 0.0, "EdgeVerificationOptions.wvv_max_radius_diff_px",
                "> 0 px");
  RequireOption(wvv_max_angle_diff_deg > 0.0, "EdgeVerificationOptions.wvv_max_angle_diff_deg",
                "> 0 deg");
  RequireOption(fit_radius_px > 0.0 && fit_radius_px <= 20.0,
                "EdgeVerificationOptions.fit_radius_px", "in (0, 20] px");
  RequireOption(inlier_threshold_px > 0.0, "EdgeVerificationOptions.inlier_threshold_px", "> 0 px");
  RequireOption(max_residual_shift_px > 0.0, "EdgeVerificationOptions.max_residual_shift_px",
                "> 0 px");
  RequireOption(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0,
                "EdgeVerificationOptions.min_inlier_fraction", "in [0, 1]");
}

void WorldViewVectorDifferences(const std::vector<Eigen::Vector2d>& a,
                                const std::vector<Eigen::Vector2d>& b, double min_radius,
                                std::vector<double>& radius_diff, std::vector<double>& angle_diff) {
  const size_t n = std::min(a.size(), b.size());
  radius_diff.assign(n, kNaN);
  angle_diff.assign(n, kNaN);
  std::vector<double> dr, dt;
  for (size_t i = 0; i < n; ++i) {
    dr.clear();
    dt.clear();
    for (size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      const Eigen::Vector2d va = a[j] - a[i], vb = b[j] - b[i];
      const double ra = va.norm();
      if (ra < min_radius) continue;
      dr.push_back(std::abs(ra - vb.norm()));
      const double t = std::atan2(va.y(), va.x()) - std::atan2(vb.y(), vb.x());
      dt.push_back(std::abs(std::remainder(t, 2.0 * std::numbers::pi)) * 180.0 / std::numbers::pi);
    }
    radius_diff[i] = Median(dr);
    angle_diff[i] = Median(dt);
  }
}

std::string EdgeVerification::BriefReport() const {
  std::ostringstream out;
  out.setf(std::ios::fixed);
  out.precision(3);
  out << ortho_edges << " ortho / " << orbital_edges
      << " orbital edge points; pairs 0/1/2/3 px: " << pairs_per_group[0] << "/"
      << pairs_per_group[1] << "/" << pairs_per_group[2] << "/" << pairs_per_group[3] << " ("
      << 100.0 * ortho_rate << "% / " << 100.0 * orbital_rate << "%); world-view-vector matches "
      << pattern_pairs;
  if (fitted) {
    out << "; residual shift " << shift_px.x() << " " << shift_px.y() << " px, " << inliers
        << " inliers, rms " << rms_px << " px";
  }
  out << (consistent ? "; consistent" : "; not consistent");
  return out.str();
}

EdgeVerification VerifyMatchWithEdges(const OrbitalMatch& match,
                                      const EdgeVerificationOptions& options) {
  options.Check();
  EdgeVerification out;
  if (!match.matched || match.orbital_patch.empty() || match.templ.empty()) return out;
  const EdgeMaps edges = DetectEdges(match, options);
  out.ortho_edges = static_cast<int>(edges.ortho_points.size());
  out.orbital_edges = cv::countNonZero(edges.orbital);
  if (edges.ortho_points.empty() || out.orbital_edges == 0) return out;
  PairEdgePoints(edges, options, out);
  CompareWorldViewVectors(options, out);
  // Robust fit: a translation voted on by every ortho edge point, or a similarity (RANSAC) on
  // the pattern pairs.
  if (options.fit_similarity) {
    FitSimilarity(options, out);
  } else {
    FitTranslation(edges, options, out);
  }
  return out;
}

}  // namespace areomap
