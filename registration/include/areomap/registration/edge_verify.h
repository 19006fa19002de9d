// Verification and refinement of an orbital match by edge points (ch. 3.4.2): Canny edges of
// the registered orthophoto and of the orbital image, edge points paired within 0-3 px
// (Table 3.7 statistics), the paired sets compared by world-view vectors (Murtagh 1992:
// every point sees the others at a radius and a polar angle; a true pair sees the same
// pattern; Fig. 3.15), then a robust translation (exhaustive one-point consensus) or
// similarity (OpenCV RANSAC on the pattern-consistent pairs). The translation is voted on by
// all edge points within fit_radius_px (a Hough vote over offsets, i.e. one-point consensus
// over every candidate correspondence), so it also sees offsets larger than 3 px.
//
// Coordinates: orbital pixel coordinates (GDAL convention, centre at +0.5) of the orbital
// image the match was made on. The residual transform maps the registered ortho's edge points
// onto the orbital ones; a correct match leaves it near identity.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "areomap/registration/orbital_match.h"

namespace areomap {

struct EdgeVerificationOptions {
  double canny_sigma_px = 1.0;          // Gaussian smoothing before Canny [px], >= 0.
  double max_pair_distance_px = 3.0;    // Pairs farther apart are not pairs (Table 3.7: 3 px).
  int max_wvv_points = 300;             // World-view vectors use at most this many pairs per
                                        // group (evenly subsampled), >= 3.
  double wvv_min_radius_px = 5.0;       // Neighbours closer than this are left out of the angle
                                        // comparison (their angle is noise), >= 0.
  double wvv_max_radius_diff_px = 1.0;  // A pair's pattern matches if its median radius
  double wvv_max_angle_diff_deg = 1.0;  // and angle differences are at most these.
  bool fit_similarity = false;          // Similarity (RANSAC) instead of translation.
  double fit_radius_px = 6.0;        // Translation fit: offsets up to this are voted on [px], > 0.
  double inlier_threshold_px = 1.0;  // Consensus / RANSAC inlier distance [px], > 0.
  double max_residual_shift_px = 1.0;  // Consistent if the fitted shift is at most this [px].
  double min_inlier_fraction = 0.3;    // ... and this fraction of the fitted points agree (all
                                       // ortho edge points for the translation vote, the
                                       // pattern pairs for the similarity).

  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

struct EdgePair {
  Eigen::Vector2d ortho_px;    // Registered ortho edge point (orbital pixel coordinates).
  Eigen::Vector2d orbital_px;  // Its nearest orbital edge point.
  double distance_px = 0.0;
  int group = 0;                    // 0: distance 0; 1: (0, 1]; 2: (1, 2]; 3: (2, 3] px.
  double wvv_radius_diff_px = 0.0;  // Median |r_ortho - r_orbital| over the group's others.
  double wvv_angle_diff_deg = 0.0;  // Median |theta_ortho - theta_orbital| [deg].
  bool pattern_match = false;
};

struct EdgeVerification {
  int ortho_edges = 0;    // Edge points of the registered orthophoto (its valid area).
  int orbital_edges = 0;  // Edge points of the orbital image in the same area.
  std::array<int, 4> pairs_per_group{};  // Table 3.7, groups as in EdgePair::group.
  double ortho_rate = 0.0;    // Paired fraction of ortho edge points (Table 3.7 "Rate1").
  double orbital_rate = 0.0;  // Paired fraction of orbital edge points ("Rate2").
  std::vector<EdgePair> pairs;
  int pattern_pairs = 0;  // Pairs whose world-view vectors match.

  // The residual transform orbital = scale R(rotation) (ortho - centre) + centre + shift,
  // fitted robustly (rotation 0 and scale 1 for a translation fit). For a translation,
  // inliers are the ortho edge points with an orbital edge within inlier_threshold_px of
  // their shifted position; for a similarity, the RANSAC inliers among the pattern pairs.
  bool fitted = false;
  Eigen::Vector2d shift_px = Eigen::Vector2d::Zero();
  double rotation_rad = 0.0;
  double scale = 1.0;
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();
  int inliers = 0;
  double rms_px = 0.0;      // RMS distance of the inliers after the fit [px].
  bool consistent = false;  // The edges confirm the match (see the options).

  std::string BriefReport() const;
};

// Verifies `match` (which must be matched and carry its template and orbital patch). A match
// without enough edges gives consistent = false, not an exception. Throws areomap::Error if
// the options fail Check().
EdgeVerification VerifyMatchWithEdges(const OrbitalMatch& match,
                                      const EdgeVerificationOptions& options = {});

// The world-view-vector differences of linked point sets (a[i] paired with b[i]): for each i,
// the median over j != i with |a[j] - a[i]| >= min_radius of |r_a - r_b| [px] and of the
// wrapped |theta_a - theta_b| [deg]. NaN where no j qualifies.
void WorldViewVectorDifferences(const std::vector<Eigen::Vector2d>& a,
                                const std::vector<Eigen::Vector2d>& b, double min_radius,
                                std::vector<double>& radius_diff, std::vector<double>& angle_diff);

}  // namespace areomap
