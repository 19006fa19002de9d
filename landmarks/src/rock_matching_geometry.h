// Internal to rock matching (rock_matching.cc, rock_matching_stages.cc): the geometry its stages
// share. Horizontal spreads of the rocks' peaks and the elliptic gates drawn with them, the
// ambiguity test, and the global pattern (the translation V = P - Q of eq. 3.29 that the rocks
// agree on, with an optional small turn). Frames: each site's rocks in its own site frame, x
// north, y east, z down [m]. docs/rocks.md ("Matching") explains the rules.
#pragma once

#include <functional>
#include <numbers>
#include <vector>

#include <Eigen/Core>

#include "areomap/landmarks/rock_extraction.h"
#include "areomap/landmarks/rock_matching.h"
#include "rock_point_grid.h"

namespace areomap::rock_matching_internal {

inline constexpr double kRadToDeg = 180.0 / std::numbers::pi;

// |x - y| against the mean of |x| and |y|; 0 where both are 0.
double RelativeDifference(double x, double y);

// The angle between two (not necessarily unit) normals [deg].
double NormalAngleDeg(const Eigen::Vector3d& n1, const Eigen::Vector3d& n2);

// The horizontal covariance of a rock's peak, turned by `rotation` (into another site's frame).
Eigen::Matrix2d HorizontalCovariance(const ExtractedRock& r,
                                     const Eigen::Matrix3d& rotation = Eigen::Matrix3d::Identity());

// The horizontal covariance of a rock's peak and its largest sigma, computed once per pair.
struct PeakSpread {
  explicit PeakSpread(const Eigen::Matrix3d& covariance_in_frame);
  Eigen::Matrix2d covariance;  // [m^2].
  double largest_sigma = 0.0;  // [m].
};

// The largest horizontal sigma of a rock's peak [m].
double LargestHorizontalSigma(const ExtractedRock& r);

// A horizontal gate about a peak, shaped by the covariance of the two peaks' difference: an
// ellipse whose semi-axis along each principal direction of the covariance is a function of the
// sigma there. A far stereo peak is uncertain along its line of sight only (eq. 4.3: range error
// grows as r^2, the azimuth error as r), so a gate drawn with its largest sigma in every
// direction takes in neighbours that its precise bearing already tells apart.
class EllipticGate {
 public:
  // Semi-axes `tolerance` + `sigmas` x sigma (the ambiguity test).
  static EllipticGate ToleranceAndSigmas(const Eigen::Matrix2d& covariance, double tolerance,
                                         double sigmas);
  // Semi-axes max(`tolerance`, 2 sigma) (eq. 3.31's epsilon, widened where the peaks smear).
  static EllipticGate AtLeast(const Eigen::Matrix2d& covariance, double tolerance);
  bool Contains(const Eigen::Vector2d& offset) const;
  double LargestSemiAxis() const;

 private:
  template <typename SemiAxis>
  EllipticGate(const Eigen::Matrix2d& covariance, SemiAxis semi_axis);
  Eigen::Matrix2d axes_;  // Principal directions (columns).
  Eigen::Vector2d semi_;  // Semi-axes along them [m], > 0.
};

// A rock is ambiguous when another rock of its site lies within the pattern tolerance plus
// `sigmas` sigmas of its peak's covariance combined with its partner's (EllipticGate: along each
// principal direction): no translation vote can tell them apart. Neighbours count when at least
// `min_height` high, or at least `similar_min_height` high with a height like the tested rock's
// (a rock measured just under the height rule here may be over it at the other site, and the
// partner's model cannot tell two rocks of one size apart).
class AmbiguityTest {
 public:
  AmbiguityTest(const std::vector<ExtractedRock>& rocks, const RockMatchingOptions& options);
  // `partner_covariance`: horizontal covariance of the peak it would be matched with, in this
  // site's frame [m^2]. `alternative`, where given, says whether a neighbour (index into the
  // site's rocks) could take the rock's place; one it rules out does not make the rock ambiguous.
  bool Ambiguous(int i, const Eigen::Matrix2d& partner_covariance = Eigen::Matrix2d::Zero(),
                 const std::function<bool(int)>& alternative = nullptr) const;

 private:
  bool Counts(const ExtractedRock& neighbour, const ExtractedRock& tested) const;
  static std::vector<int> Neighbours(const std::vector<ExtractedRock>& rocks,
                                     const RockMatchingOptions& options);
  static std::vector<Eigen::Vector2d> Peaks(const std::vector<ExtractedRock>& rocks,
                                            const std::vector<int>& indices);
  const std::vector<ExtractedRock>& rocks_;
  const std::vector<int> neighbours_;
  const RockMatchingOptions& options_;
  rock_internal::PointGrid grid_;
};

// Search radius around a rock of a at `peak`: the pattern tolerance plus three sigmas of the
// prior's displacement there (its position sigma and its heading sigma acting on the distance
// from site b's camera, about which b's rocks are turned), capped at options.search_radius_m.
double SearchRadius(const Eigen::Vector3d& peak, const Eigen::Vector3d& camera_b_in_a,
                    const RockMatchingPrior& prior, const RockMatchingOptions& options);

// A pattern candidate's translation V = P - Q (eq. 3.29) and the rock of site a it was found for.
struct CandidateVector {
  int rock = -1;  // Index of the rock of a among those with candidates.
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  Eigen::Vector3d q = Eigen::Vector3d::Zero();  // The candidate of b, in a's frame [m].
};

// The global pattern's translation from the candidate vectors of all rocks. Ch. 3.2 takes their
// median. With `consensus`, it is the median of the largest group of rocks that agree: the
// candidate vector that the most rocks have a vector within `agreement_m` of (horizontally; ties:
// the smaller summed distance of those vectors, then the first), and of each such rock its vector
// nearest it. Where no two rocks agree, the median of all. (Few rocks with a prior off by 2 m: the
// wrong candidates scatter about the prior and pull the median halfway, so the true pattern's
// vectors all fail the deviation test; docs/rocks.md, "The pattern's consensus".)
Eigen::Vector3d GlobalTranslation(const std::vector<CandidateVector>& vectors, bool consensus,
                                  double agreement_m);

// The global pattern as a motion: the translation V at `pivot` and a small turn about the z axis,
// so that the V expected of a candidate at q (in a's frame) is V + turn x (q - pivot).
struct PatternMotion {
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();  // [m].
  Eigen::Vector2d pivot = Eigen::Vector2d::Zero();        // [m], in a's frame.
  double turn_rad = 0.0;
  Eigen::Vector3d ExpectedV(const Eigen::Vector3d& q) const {
    const Eigen::Vector2d d = q.head<2>() - pivot;
    return translation + turn_rad * Eigen::Vector3d(-d.y(), d.x(), 0.0);
  }
};

// The turn of the global pattern: of each rock, its candidate vector nearest `translation`
// (within agreement_m horizontally); V_i = t + turn x (q_i - pivot) fitted by least squares to
// them, then again to those within trim_m of the first fit. No turn (the translation alone)
// where fewer than three rocks agree, where their candidates spread less than 1 m (rms) about
// their centre (the turn is not determined), or where the fitted turn exceeds max_turn_rad.
PatternMotion FitPatternMotion(const std::vector<CandidateVector>& vectors,
                               const Eigen::Vector3d& translation, double agreement_m,
                               double trim_m, double max_turn_rad);

}  // namespace areomap::rock_matching_internal
