#include "areomap/adjustment/traverse_anchoring.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Eigenvalues>

#include "areomap/map/error.h"

namespace areomap {

ErrorEllipse HorizontalErrorEllipse(const Eigen::Matrix2d& covariance_north_east) {
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eigen(covariance_north_east);
  ErrorEllipse e;
  e.semi_major_m = std::sqrt(std::max(0.0, eigen.eigenvalues()[1]));
  e.semi_minor_m = std::sqrt(std::max(0.0, eigen.eigenvalues()[0]));
  const Eigen::Vector2d major = eigen.eigenvectors().col(1);  // (north, east)
  double azimuth = std::atan2(major.y(), major.x());          // Clockwise from north.
  if (azimuth < 0.0) azimuth += std::numbers::pi;
  if (azimuth >= std::numbers::pi) azimuth -= std::numbers::pi;
  e.azimuth_rad = azimuth;
  return e;
}

AnchoredTraverse AnchorTraverse(const BundleInput& input, const BundleResult& result,
                                const std::vector<Eigen::Vector3d>& truth) {
  const size_t n = result.sites.size();
  if (!truth.empty() && truth.size() != n) {
    throw Error("traverse anchoring: " + std::to_string(truth.size()) + " true positions for " +
                std::to_string(n) + " sites");
  }
  const Rigid3d mbf_from_traverse = SiteFromMbf(input.body, input.origin).Inverse();
  const Eigen::Matrix3d r = mbf_from_traverse.RotationMatrix();
  AnchoredTraverse out;
  for (size_t k = 0; k < n; ++k) {
    const SiteReport& s = result.sites[k];
    AnchoredSite a;
    a.site = s.site;
    a.initial_in_traverse = s.initial.translation;
    a.position_in_traverse = s.adjusted.translation;
    a.covariance_in_traverse = s.covariance.block<3, 3>(3, 3);
    a.position_mbf = mbf_from_traverse * a.position_in_traverse;
    a.covariance_mbf = r * a.covariance_in_traverse * r.transpose();
    a.geographic = GeographicFromMbf(input.body, a.position_mbf);
    a.ellipse = HorizontalErrorEllipse(a.covariance_in_traverse.topLeftCorner<2, 2>());
    a.sigma_down_m = std::sqrt(std::max(0.0, a.covariance_in_traverse(2, 2)));
    a.only_priors = s.only_priors;
    if (!truth.empty()) {
      a.truth_in_traverse = truth[k];
      a.initial_error_m = (a.initial_in_traverse - truth[k]).head<2>().norm();
      a.adjusted_error_m = (a.position_in_traverse - truth[k]).head<2>().norm();
    }
    out.sites.push_back(a);
  }
  std::vector<double> adjusted_re;
  for (size_t k = 1; k < n; ++k) {
    const AnchoredSite& a = out.sites[k - 1];
    const AnchoredSite& b = out.sites[k];
    LegError leg;
    leg.site_a = a.site;
    leg.site_b = b.site;
    const Eigen::Vector2d adjusted = (b.position_in_traverse - a.position_in_traverse).head<2>();
    leg.length_m = adjusted.norm();
    if (!truth.empty()) {
      const Eigen::Vector2d true_leg = (truth[k] - truth[k - 1]).head<2>();
      leg.length_m = true_leg.norm();
      const Eigen::Vector2d initial = (b.initial_in_traverse - a.initial_in_traverse).head<2>();
      leg.initial_re = (initial - true_leg).norm() / leg.length_m;
      leg.adjusted_re = (adjusted - true_leg).norm() / leg.length_m;
      adjusted_re.push_back(leg.adjusted_re);
    }
    const Matrix6d relative =
        result.RelativeCovariance(static_cast<int>(k - 1), static_cast<int>(k));
    leg.predicted_re =
        std::sqrt(std::max(0.0, relative(3, 3) + relative(4, 4))) / std::max(leg.length_m, 1e-9);
    out.length_m += leg.length_m;
    out.legs.push_back(leg);
  }
  if (!truth.empty() && n > 0) {
    out.initial_end_error_m = out.sites.back().initial_error_m;
    out.adjusted_end_error_m = out.sites.back().adjusted_error_m;
    if (!adjusted_re.empty()) {
      std::nth_element(adjusted_re.begin(), adjusted_re.begin() + adjusted_re.size() / 2,
                       adjusted_re.end());
      out.median_adjusted_re = adjusted_re[adjusted_re.size() / 2];
    }
  }
  return out;
}

}  // namespace areomap
