// BundleInput and BundleOptions: their checks, and the pose covariances the callers build
// priors with (bundle_adjustment.h).
#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "areomap/adjustment/bundle_adjustment.h"
#include "areomap/map/error.h"
#include "bundle_checks.h"

namespace areomap {
namespace bundle_internal {

void CheckSite(int site, int count, const std::string& what) {
  if (site < 0 || site >= count) {
    throw Error("bundle input: " + what + ": site " + std::to_string(site) + " is not in [0, " +
                std::to_string(count) + ")");
  }
}

}  // namespace bundle_internal

namespace {

void CheckFinite(const Eigen::MatrixXd& m, const std::string& what) {
  if (!m.allFinite()) throw Error("bundle input: " + what + " is not finite");
}

}  // namespace

using bundle_internal::CheckSite;

Matrix6d PoseCovarianceFromSigmas(const Eigen::Vector3d& rotation_sigma_rad,
                                  const Eigen::Vector3d& translation_sigma_m) {
  Vector6d sigmas;
  sigmas << rotation_sigma_rad, translation_sigma_m;
  return sigmas.cwiseAbs2().asDiagonal();
}

Matrix6d DeadReckoningCovariance(const Eigen::Vector3d& leg_in_a, double scale_sigma,
                                 double heading_sigma_rad, const Vector6d& floor_sigmas) {
  // Error of (rotation vector, translation) = s * d_s + drift * d_drift.
  // The scale error acts on the horizontal leg: heights come from the inclinometers.
  const Eigen::Vector3d horizontal(leg_in_a.x(), leg_in_a.y(), 0.0);
  Vector6d d_scale, d_drift;
  d_scale << 0, 0, 0, horizontal;
  d_drift << Eigen::Vector3d::UnitZ(), Eigen::Vector3d::UnitZ().cross(horizontal);
  const double s2 = scale_sigma * scale_sigma, h2 = heading_sigma_rad * heading_sigma_rad;
  Matrix6d c = s2 * d_scale * d_scale.transpose() + h2 * d_drift * d_drift.transpose();
  // Second-order terms of (1 + s) Rz(drift) d - d, linearized at the measured leg: (s^2 +
  // drift^2 / 2) along the leg and 2 s drift across it (variances 3 s^4 + 3/4 drift^4, 4 s^2
  // drift^2 for Gaussian s and drift). They exceed any small floor on long legs.
  const double length2 = horizontal.squaredNorm();
  if (length2 > 0.0) {
    const Eigen::Vector3d u = horizontal.normalized();
    const Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(u);
    c.bottomRightCorner<3, 3>() += (3.0 * s2 * s2 + 0.75 * h2 * h2) * length2 * u * u.transpose() +
                                   4.0 * s2 * h2 * length2 * across * across.transpose();
  }
  c.diagonal() += floor_sigmas.cwiseAbs2();
  return c;
}

std::string ToString(ObservationKind kind) {
  switch (kind) {
    case ObservationKind::kTiePoint:
      return "tie_point";
    case ObservationKind::kControlPoint:
      return "control_point";
    case ObservationKind::kPosePrior:
      return "pose_prior";
    case ObservationKind::kHeight:
      return "height";
  }
  return "unknown";
}

void BundleInput::Check() const {
  if (site_count < 1) throw Error("bundle input: site_count must be at least 1");
  body.Check();
  if (!IsValid(origin)) throw Error("bundle input: origin is not a valid lat/lon/h");
  if (!initial_poses.empty() && static_cast<int>(initial_poses.size()) != site_count) {
    throw Error("bundle input: " + std::to_string(initial_poses.size()) + " initial poses for " +
                std::to_string(site_count) + " sites");
  }
  std::set<std::string> ids;
  for (const TiePoint& t : tie_points) {
    const std::string what = "tie point '" + t.id + "'";
    CheckSite(t.site_a, site_count, what + " site_a");
    CheckSite(t.site_b, site_count, what + " site_b");
    if (t.site_a == t.site_b) throw Error("bundle input: " + what + ": site_a equals site_b");
    CheckFinite(t.position_in_a, what + " position_in_a");
    CheckFinite(t.position_in_b, what + " position_in_b");
    if (!ids.insert(t.id).second) throw Error("bundle input: duplicate point id '" + t.id + "'");
  }
  for (const ControlPoint& c : control_points) {
    const std::string what = "control point '" + c.id + "'";
    CheckSite(c.site, site_count, what);
    CheckFinite(c.position_in_site, what + " position_in_site");
    CheckFinite(c.position_mbf, what + " position_mbf");
    if (!ids.insert(c.id).second) throw Error("bundle input: duplicate point id '" + c.id + "'");
  }
  for (const RelativePosePrior& p : priors) {
    const std::string what =
        "pose prior " + std::to_string(p.site_a) + "-" + std::to_string(p.site_b);
    CheckSite(p.site_a, site_count, what);
    CheckSite(p.site_b, site_count, what);
    if (p.site_a == p.site_b) throw Error("bundle input: " + what + ": site_a equals site_b");
    CheckFinite(p.a_from_b.translation, what + " translation");
  }
  std::map<std::string, std::vector<int>> landmark_sites;
  for (const TiePoint& t : tie_points) landmark_sites[t.id] = {t.site_a, t.site_b};
  for (const ControlPoint& c : control_points) landmark_sites[c.id] = {c.site};
  for (const ImageObservation& o : image_observations) {
    const std::string what = "image observation of '" + o.landmark_id + "' in '" + o.image + "'";
    const auto landmark = landmark_sites.find(o.landmark_id);
    if (landmark == landmark_sites.end()) {
      throw Error("bundle input: " + what + ": no tie point or control point has that id");
    }
    if (std::find(landmark->second.begin(), landmark->second.end(), o.site) ==
        landmark->second.end()) {
      throw Error("bundle input: " + what + ": site " + std::to_string(o.site) +
                  " is not one of the landmark's sites");
    }
    if (!(o.sigma_px > 0.0) || !o.pixel.allFinite()) {
      throw Error("bundle input: " + what + ": expected a finite pixel and a positive sigma_px");
    }
  }
  for (const SiteHeight& h : heights) {
    CheckSite(h.site, site_count, "height");
    if (!(h.sigma_m > 0.0) || !std::isfinite(h.height_m)) {
      throw Error("bundle input: height of site " + std::to_string(h.site) +
                  ": expected a finite height and a positive sigma_m");
    }
  }
}

void BundleOptions::Check() const {
  RequireOption(huber_scale > 0.0, "BundleOptions.huber_scale", "> 0 sigmas");
  RequireOption(rejection_alpha > 0.0 && rejection_alpha < 0.5, "BundleOptions.rejection_alpha",
                "in (0, 0.5)");
  RequireOption(max_rejection_rounds >= 0, "BundleOptions.max_rejection_rounds", ">= 0");
  RequireOption(max_iterations >= 1, "BundleOptions.max_iterations", ">= 1");
  RequireOption(num_threads >= 1, "BundleOptions.num_threads", ">= 1");
}

}  // namespace areomap
