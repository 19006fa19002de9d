#include "areomap/landmarks/leg_consistency.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>

#include <boost/math/distributions/fisher_f.hpp>
#include <nlohmann/json.hpp>

#include "areomap/map/error.h"

namespace areomap {
namespace {

// chi2 and redundancy of one conformal fit, or of several pooled.
struct FitSum {
  double chi2 = 0.0;
  int redundancy = 0;
  double Sigma0Squared() const { return chi2 / static_cast<double>(redundancy); }
};

std::optional<FitSum> LegFit(const std::vector<PlanarTiePoint>& ties) {
  if (ties.size() < 3) return std::nullopt;
  const std::optional<ConformalTransform2d> fit = FitConformalTransform(ties);
  if (!fit || fit->redundancy <= 0 || !std::isfinite(fit->chi2)) return std::nullopt;
  return FitSum{fit->chi2, fit->redundancy};
}

// The leg's F test against `reference` (which must have redundancy and a positive chi2).
void Evaluate(const FitSum& leg, const FitSum& reference, double alpha, LegConsistency* v) {
  v->tested = true;
  v->sigma0_squared = leg.Sigma0Squared();
  v->redundancy = leg.redundancy;
  v->reference_sigma0_squared = reference.Sigma0Squared();
  v->reference_redundancy = reference.redundancy;
  v->f_statistic = v->sigma0_squared / v->reference_sigma0_squared;
  const boost::math::fisher_f f(leg.redundancy, reference.redundancy);
  v->f_threshold = boost::math::quantile(f, 1.0 - alpha);
}

}  // namespace

void LegConsistencyOptions::Check() const {
  RequireOption(alpha > 0.0 && alpha < 1.0, "LegConsistencyOptions.alpha", "in (0, 1)");
  RequireOption(max_residual_chi2 > 0.0, "LegConsistencyOptions.max_residual_chi2", "> 0");
  RequireOption(min_tie_points >= 2, "LegConsistencyOptions.min_tie_points", ">= 2");
}

nlohmann::json LegConsistency::ToJson() const {
  if (!tested) return {{"tested", false}};
  return {{"tested", true},
          {"sigma0_squared", sigma0_squared},
          {"redundancy", redundancy},
          {"reference_sigma0_squared", reference_sigma0_squared},
          {"reference_redundancy", reference_redundancy},
          {"f_statistic", f_statistic},
          {"f_threshold", f_threshold},
          {"first_f_statistic", first_f_statistic},
          {"dropped", dropped},
          {"excluded", excluded}};
}

PlanarTiePoint PlanarTie(const TiePoint& tie) {
  PlanarTiePoint t;
  t.in_current = tie.position_in_a.head<2>();
  t.covariance_current = tie.covariance_in_a.topLeftCorner<2, 2>();
  t.in_adjacent = tie.position_in_b.head<2>();
  t.covariance_adjacent = tie.covariance_in_b.topLeftCorner<2, 2>();
  return t;
}

std::vector<LegConsistency> TestLegConsistency(const std::vector<std::vector<TiePoint>>& legs,
                                               const LegConsistencyOptions& options) {
  options.Check();
  const size_t n = legs.size();
  std::vector<std::vector<PlanarTiePoint>> planar(n);
  std::vector<std::optional<FitSum>> fits(n);
  for (size_t i = 0; i < n; ++i) {
    for (const TiePoint& t : legs[i]) planar[i].push_back(PlanarTie(t));
    fits[i] = LegFit(planar[i]);
  }
  // The pooled fits of the legs other than `leg` that are not failing; nullopt when there is
  // nothing to compare with.
  std::vector<char> failing(n, 0);
  const auto reference = [&](size_t leg) -> std::optional<FitSum> {
    FitSum sum;
    for (size_t j = 0; j < n; ++j) {
      if (j == leg || failing[j] || !fits[j]) continue;
      sum.chi2 += fits[j]->chi2;
      sum.redundancy += fits[j]->redundancy;
    }
    if (sum.redundancy == 0 || !(sum.chi2 > 0.0)) return std::nullopt;
    return sum;
  };
  std::vector<LegConsistency> out(n);
  // Legs that fail against the others are left out of the reference, all of a round at once,
  // until a round finds no new one (failing only grows, so at most n rounds).
  for (bool grew = true; grew;) {
    grew = false;
    std::vector<char> now_failing = failing;
    for (size_t i = 0; i < n; ++i) {
      if (!fits[i] || failing[i]) continue;
      const std::optional<FitSum> ref = reference(i);
      if (!ref) continue;
      LegConsistency v;
      Evaluate(*fits[i], *ref, options.alpha, &v);
      if (v.Failed()) now_failing[i] = grew = true;
    }
    failing.swap(now_failing);
  }
  for (size_t i = 0; i < n; ++i) {
    if (!fits[i]) continue;
    const std::optional<FitSum> ref = reference(i);
    if (!ref) continue;
    LegConsistency& v = out[i];
    Evaluate(*fits[i], *ref, options.alpha, &v);
    v.first_f_statistic = v.f_statistic;
    // Data snooping at the reference's precision: the covariances scaled by its variance factor
    // scale every leave-one-out chi-square by its inverse.
    std::vector<PlanarTiePoint> ties = planar[i];
    std::vector<int> index(ties.size());
    std::iota(index.begin(), index.end(), 0);
    bool fit_lost = false;  // the tie points left could not be fitted
    while (v.Failed() && static_cast<int>(ties.size()) > options.min_tie_points) {
      const std::vector<double> chi2 = LeaveOneOutChi2(ties);
      size_t worst = 0;
      double worst_chi2 = 0.0;
      for (size_t k = 0; k < chi2.size(); ++k) {
        const double scaled = chi2[k] / v.reference_sigma0_squared;
        if (scaled > worst_chi2) {  // NaN (the others not fittable) never is
          worst_chi2 = scaled;
          worst = k;
        }
      }
      if (worst_chi2 <= options.max_residual_chi2) break;
      v.dropped.push_back(index[worst]);
      ties.erase(ties.begin() + static_cast<long>(worst));
      index.erase(index.begin() + static_cast<long>(worst));
      const std::optional<FitSum> fit = LegFit(ties);
      if (!fit) {
        fit_lost = true;
        break;
      }
      Evaluate(*fit, *ref, options.alpha, &v);
    }
    v.excluded = v.Failed() || fit_lost;
  }
  return out;
}

}  // namespace areomap
