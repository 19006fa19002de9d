// BundleResult: relative covariances, the one-line report and the JSON of adjustment.json
// (bundle_adjustment.h).
#include <cstdio>
#include <string>

#include <nlohmann/json.hpp>

#include "areomap/adjustment/bundle_adjustment.h"

namespace areomap {

Matrix6d BundleResult::RelativeCovariance(int site_a, int site_b) const {
  if (pose_covariance.rows() == 0) return Matrix6d::Zero();
  const auto block = [&](int i, int j) -> Matrix6d {
    return pose_covariance.block<6, 6>(6 * i, 6 * j);
  };
  return block(site_a, site_a) + block(site_b, site_b) - block(site_a, site_b) -
         block(site_b, site_a);
}

std::string BundleResult::BriefReport() const {
  int only_priors = 0;
  for (const SiteReport& s : sites) only_priors += s.only_priors ? 1 : 0;
  char text[400];
  std::snprintf(text, sizeof(text),
                "bundle adjustment: %zu sites, %zu observation groups, %d rejected in %d rounds; "
                "sigma0 %.3f (redundancy %d); %d iterations, %s; solve %.3f s, covariance %.3f "
                "s; %d sites linked by priors only",
                sites.size(), observations.size(), rejected, rejection_rounds, sigma0, redundancy,
                iterations, termination.c_str(), solve_seconds, covariance_seconds, only_priors);
  return text;
}

nlohmann::json ToJson(const BundleResult& result) {
  nlohmann::json sites = nlohmann::json::array();
  for (const SiteReport& s : result.sites) {
    const auto pose = [](const Rigid3d& p) {
      const Eigen::Quaterniond& q = p.rotation;
      return nlohmann::json{
          {"position_m", {p.translation.x(), p.translation.y(), p.translation.z()}},
          {"rotation_wxyz", {q.w(), q.x(), q.y(), q.z()}}};
    };
    nlohmann::json covariance = nlohmann::json::array();
    for (int r = 0; r < 6; ++r) {
      nlohmann::json row = nlohmann::json::array();
      for (int c = 0; c < 6; ++c) row.push_back(s.covariance(r, c));
      covariance.push_back(row);
    }
    sites.push_back({{"site", s.site},
                     {"initial", pose(s.initial)},
                     {"adjusted", pose(s.adjusted)},
                     {"shift_m", (s.adjusted.translation - s.initial.translation).norm()},
                     {"covariance", covariance},
                     {"held", s.held},
                     {"tie_points", s.tie_points},
                     {"control_points", s.control_points},
                     {"heights", s.heights},
                     {"only_priors", s.only_priors}});
  }
  nlohmann::json observations = nlohmann::json::array();
  for (const ObservationReport& o : result.observations) {
    nlohmann::json j = {{"kind", ToString(o.kind)},
                        {"id", o.id},
                        {"sites", o.sites},
                        {"chi2", o.chi2},
                        {"dof", o.dof},
                        {"threshold", o.threshold},
                        {"residual", o.residual_m},
                        {"rejected", o.rejected}};
    if (o.rejected) j["reason"] = o.reason;
    observations.push_back(j);
  }
  nlohmann::json images = nlohmann::json::array();
  for (const ImageReport& i : result.images) {
    images.push_back({{"image", i.image}, {"observations", i.observations}, {"rms_px", i.rms_px}});
  }
  return {{"sigma0", result.sigma0},
          {"redundancy", result.redundancy},
          {"rejected", result.rejected},
          {"rejection_rounds", result.rejection_rounds},
          {"iterations", result.iterations},
          {"converged", result.converged},
          {"termination", result.termination},
          {"solve_seconds", result.solve_seconds},
          {"covariance_seconds", result.covariance_seconds},
          {"sites", sites},
          {"observations", observations},
          {"images", images}};
}

}  // namespace areomap
