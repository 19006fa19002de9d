// Internal to rock matching: the geometry its stages share (rock_matching_geometry.h).
#include "rock_matching_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

namespace areomap::rock_matching_internal {

namespace {

double Median(std::vector<double> values) {
  if (values.empty()) return 0.0;
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + mid, values.end());
  const double upper = values[mid];
  if (values.size() % 2 == 1) return upper;
  return 0.5 * (upper + *std::max_element(values.begin(), values.begin() + mid));
}

Eigen::Vector3d ComponentMedian(const std::vector<CandidateVector>& vectors) {
  std::vector<double> x, y, z;
  for (const CandidateVector& c : vectors) {
    x.push_back(c.v.x());
    y.push_back(c.v.y());
    z.push_back(c.v.z());
  }
  return {Median(x), Median(y), Median(z)};
}

// Of each rock, its vector nearest `centre` within agreement_m horizontally: rock -> (distance,
// index into vectors).
std::map<int, std::pair<double, size_t>> NearestPerRock(const std::vector<CandidateVector>& vectors,
                                                        const Eigen::Vector3d& centre,
                                                        double agreement_m) {
  std::map<int, std::pair<double, size_t>> nearest;
  for (size_t j = 0; j < vectors.size(); ++j) {
    const double d = (vectors[j].v - centre).head<2>().norm();
    if (d > agreement_m) continue;
    const auto [it, inserted] = nearest.try_emplace(vectors[j].rock, d, j);
    if (!inserted && d < it->second.first) it->second = {d, j};
  }
  return nearest;
}

}  // namespace

double RelativeDifference(double x, double y) {
  const double mean = 0.5 * (std::abs(x) + std::abs(y));
  return mean > 0.0 ? std::abs(x - y) / mean : 0.0;
}

double NormalAngleDeg(const Eigen::Vector3d& n1, const Eigen::Vector3d& n2) {
  return std::acos(std::clamp(n1.normalized().dot(n2.normalized()), -1.0, 1.0)) * kRadToDeg;
}

Eigen::Matrix2d HorizontalCovariance(const ExtractedRock& r, const Eigen::Matrix3d& rotation) {
  return (rotation * r.peak_covariance * rotation.transpose()).topLeftCorner<2, 2>();
}

PeakSpread::PeakSpread(const Eigen::Matrix3d& covariance_in_frame)
    : covariance(covariance_in_frame.topLeftCorner<2, 2>()) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen;
  eigen.computeDirect(covariance, Eigen::EigenvaluesOnly);
  largest_sigma = std::sqrt(std::max(0.0, eigen.eigenvalues().maxCoeff()));
}

double LargestHorizontalSigma(const ExtractedRock& r) {
  return PeakSpread(r.peak_covariance).largest_sigma;
}

template <typename SemiAxis>
EllipticGate::EllipticGate(const Eigen::Matrix2d& covariance, SemiAxis semi_axis) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen;
  eigen.computeDirect(covariance);
  axes_ = eigen.eigenvectors();
  for (int k = 0; k < 2; ++k) {
    semi_[k] = semi_axis(std::sqrt(std::max(0.0, eigen.eigenvalues()[k])));
  }
}

EllipticGate EllipticGate::ToleranceAndSigmas(const Eigen::Matrix2d& covariance, double tolerance,
                                              double sigmas) {
  return EllipticGate(covariance, [&](double sigma) { return tolerance + sigmas * sigma; });
}

EllipticGate EllipticGate::AtLeast(const Eigen::Matrix2d& covariance, double tolerance) {
  return EllipticGate(covariance, [&](double sigma) { return std::max(tolerance, 2.0 * sigma); });
}

bool EllipticGate::Contains(const Eigen::Vector2d& offset) const {
  return (axes_.transpose() * offset).cwiseQuotient(semi_).squaredNorm() <= 1.0;
}

double EllipticGate::LargestSemiAxis() const { return semi_.maxCoeff(); }

AmbiguityTest::AmbiguityTest(const std::vector<ExtractedRock>& rocks,
                             const RockMatchingOptions& options)
    : rocks_(rocks),
      neighbours_(Neighbours(rocks, options)),
      options_(options),
      grid_(Peaks(rocks, neighbours_), 1.0) {}

bool AmbiguityTest::Ambiguous(int i, const Eigen::Matrix2d& partner_covariance,
                              const std::function<bool(int)>& alternative) const {
  const ExtractedRock& r = rocks_[i];
  const EllipticGate gate =
      EllipticGate::ToleranceAndSigmas(HorizontalCovariance(r) + partner_covariance,
                                       options_.pattern_tolerance_m, options_.ambiguity_sigmas);
  bool ambiguous = false;
  grid_.ForEachNear(r.peak.head<2>(), gate.LargestSemiAxis(), [&](int k) {
    const int j = neighbours_[k];
    ambiguous = ambiguous || (j != i && Counts(rocks_[j], r) &&
                              gate.Contains((rocks_[j].peak - r.peak).head<2>()) &&
                              (!alternative || alternative(j)));
  });
  return ambiguous;
}

bool AmbiguityTest::Counts(const ExtractedRock& neighbour, const ExtractedRock& tested) const {
  return neighbour.height_m >= options_.ambiguity_min_height_m ||
         RelativeDifference(neighbour.height_m, tested.height_m) <=
             options_.ambiguity_similar_height_difference;
}

std::vector<int> AmbiguityTest::Neighbours(const std::vector<ExtractedRock>& rocks,
                                           const RockMatchingOptions& options) {
  const double lowest =
      std::min(options.ambiguity_min_height_m, options.ambiguity_similar_min_height_m);
  std::vector<int> indices;
  for (size_t i = 0; i < rocks.size(); ++i) {
    if (rocks[i].height_m >= lowest) indices.push_back(static_cast<int>(i));
  }
  return indices;
}

std::vector<Eigen::Vector2d> AmbiguityTest::Peaks(const std::vector<ExtractedRock>& rocks,
                                                  const std::vector<int>& indices) {
  std::vector<Eigen::Vector2d> xy;
  for (int i : indices) xy.push_back(rocks[i].peak.head<2>());
  return xy;
}

double SearchRadius(const Eigen::Vector3d& peak, const Eigen::Vector3d& camera_b_in_a,
                    const RockMatchingPrior& prior, const RockMatchingOptions& options) {
  if (std::isinf(prior.position_sigma_m)) return options.search_radius_m;
  const double lever =
      (peak - camera_b_in_a).head<2>().norm() * prior.heading_sigma_deg / kRadToDeg;
  const double sigma = std::hypot(prior.position_sigma_m, lever);
  return std::min(options.search_radius_m, options.pattern_tolerance_m + 3.0 * sigma);
}

Eigen::Vector3d GlobalTranslation(const std::vector<CandidateVector>& vectors, bool consensus,
                                  double agreement_m) {
  if (!consensus) return ComponentMedian(vectors);
  std::map<int, std::pair<double, size_t>> best;
  double best_spread = std::numeric_limits<double>::infinity();
  for (const CandidateVector& seed : vectors) {
    auto nearest = NearestPerRock(vectors, seed.v, agreement_m);
    double spread = 0.0;
    for (const auto& [rock, entry] : nearest) spread += entry.first;
    if (nearest.size() > best.size() || (nearest.size() == best.size() && spread < best_spread)) {
      best = std::move(nearest);
      best_spread = spread;
    }
  }
  if (best.size() < 2) return ComponentMedian(vectors);
  std::vector<CandidateVector> group;
  for (const auto& [rock, entry] : best) group.push_back(vectors[entry.second]);
  return ComponentMedian(group);
}

PatternMotion FitPatternMotion(const std::vector<CandidateVector>& vectors,
                               const Eigen::Vector3d& translation, double agreement_m,
                               double trim_m, double max_turn_rad) {
  PatternMotion motion;
  motion.translation = translation;
  std::vector<const CandidateVector*> group;
  for (const auto& [rock, entry] : NearestPerRock(vectors, translation, agreement_m)) {
    group.push_back(&vectors[entry.second]);
  }
  for (int pass = 0; pass < 2; ++pass) {
    if (group.size() < 3) return motion;
    Eigen::Vector2d pivot = Eigen::Vector2d::Zero();
    for (const CandidateVector* c : group) pivot += c->q.head<2>();
    pivot /= static_cast<double>(group.size());
    Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
    Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
    double spread = 0.0;
    for (const CandidateVector* c : group) {
      const Eigen::Vector2d d = c->q.head<2>() - pivot;
      spread += d.squaredNorm();
      const Eigen::Vector3d row_x(1.0, 0.0, -d.y()), row_y(0.0, 1.0, d.x());
      normal += row_x * row_x.transpose() + row_y * row_y.transpose();
      rhs += row_x * c->v.x() + row_y * c->v.y();
    }
    if (spread / static_cast<double>(group.size()) < 1.0) return motion;
    const Eigen::Vector3d x = normal.ldlt().solve(rhs);
    if (!x.allFinite() || std::abs(x.z()) > max_turn_rad) return motion;
    PatternMotion fitted;
    fitted.translation = Eigen::Vector3d(x.x(), x.y(), translation.z());
    fitted.pivot = pivot;
    fitted.turn_rad = x.z();
    if (pass == 1) return fitted;
    std::vector<const CandidateVector*> kept;
    for (const CandidateVector* c : group) {
      if ((c->v - fitted.ExpectedV(c->q)).head<2>().norm() <= trim_m) kept.push_back(c);
    }
    group = std::move(kept);
  }
  return motion;
}

}  // namespace areomap::rock_matching_internal
