// Guided re-registration of one site (a unit of `areomap run` after an adjustment): the site's
// orthophoto, still at its telemetry georeference, is matched again on the orbital image around
// where the adjustment puts the rover and how it turns it, in a window sized by the adjusted
// covariance, with the chance-level test on (OrbitalMatchOptions::null_windows).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "areomap/map/error.h"
#include "mission_units.h"

namespace areomap {
namespace mission_run {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

std::string ThreeDigits(int n) {
  char text[16];
  std::snprintf(text, sizeof(text), "%03d", n);
  return text;
}

Eigen::Vector3d Vector3(const json& value, const std::string& what) {
  const auto v = value.get<std::vector<double>>();
  if (v.size() != 3) throw Error(what + ": expected 3 numbers");
  return {v[0], v[1], v[2]};
}

Eigen::Quaterniond Quaternion(const json& value, const std::string& what) {
  const auto q = value.get<std::vector<double>>();
  if (q.size() != 4) throw Error(what + ": expected rotation_wxyz [4]");
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]).normalized();
}

GuidedPriorRecord PriorRecord(const GuidedPrior& prior) {
  return {prior.shift_en_m.x(), prior.shift_en_m.y(), prior.rotation_rad * 180.0 / std::numbers::pi,
          prior.sigma_m};
}

// Whether a finished unit was guided by (practically) the same prior: 1 mm, 1e-4 degrees.
bool SamePrior(const GuidedPriorRecord& recorded, const GuidedPrior& prior) {
  const GuidedPriorRecord now = PriorRecord(prior);
  return std::abs(recorded.shift_east_m - now.shift_east_m) <= 1e-3 &&
         std::abs(recorded.shift_north_m - now.shift_north_m) <= 1e-3 &&
         std::abs(recorded.rotation_deg - now.rotation_deg) <= 1e-4 &&
         std::abs(recorded.sigma_m - now.sigma_m) <= 1e-3;
}

}  // namespace
}  // namespace mission_run

GuidedPrior GuidedPriorFromPoses(const Rigid3d& telemetry, const Rigid3d& adjusted,
                                 const Matrix6d& covariance, double sigma_floor_m) {
  if (!covariance.allFinite() || !telemetry.translation.allFinite() ||
      !adjusted.translation.allFinite() || !adjusted.rotation.coeffs().allFinite()) {
    throw Error("guided prior: the adjusted pose or its covariance is not finite");
  }
  const Eigen::Matrix3d turn =
      (telemetry.rotation.inverse() * adjusted.rotation).toRotationMatrix();
  const Eigen::Vector3d moved = adjusted.translation - telemetry.translation;
  const double largest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(
                             covariance.block<2, 2>(3, 3), Eigen::EigenvaluesOnly)
                             .eigenvalues()
                             .maxCoeff();
  GuidedPrior prior;
  prior.shift_en_m = Eigen::Vector2d(moved.y(), moved.x());
  // A turn from north towards east (about z, down) is clockwise on the map.
  prior.rotation_rad = -std::atan2(turn(1, 0), turn(0, 0));
  prior.sigma_m = std::max(sigma_floor_m, std::sqrt(std::max(largest, 0.0)));
  return prior;
}

namespace mission_run {

GuidedPrior GuidedPriorFromAdjustment(const json& site, double sigma_floor_m) {
  const std::string what = "adjustment.json: site " + std::to_string(site.value("site", -1));
  try {
    const auto pose = [&](const char* which) {
      return Rigid3d(Quaternion(site.at(which).at("rotation_wxyz"), what),
                     Vector3(site.at(which).at("position_m"), what));
    };
    const auto rows = site.at("covariance").get<std::vector<std::vector<double>>>();
    Matrix6d covariance;
    for (int r = 0; r < 6; ++r) {
      if (rows.size() != 6 || rows[r].size() != 6) {
        throw Error(what + ": expected a 6 x 6 \"covariance\"");
      }
      for (int c = 0; c < 6; ++c) covariance(r, c) = rows[r][c];
    }
    return GuidedPriorFromPoses(pose("initial"), pose("adjusted"), covariance, sigma_floor_m);
  } catch (const json::exception& e) {
    throw Error(what + ": expected initial/adjusted position_m, rotation_wxyz and covariance (" +
                e.what() + ")");
  }
}

fs::path GuidedDir(const RunContext& run, int pass, int site) {
  return run.out_dir / "guided" / ("pass_" + std::to_string(pass)) / ("site_" + ThreeDigits(site));
}

GuidedUnitResult RunGuidedRegistrationUnit(const RunContext& run, size_t site_index, int pass,
                                           const GuidedPrior& guided) {
  const MissionSite& site = run.mission->sites.at(site_index);
  const fs::path dir = GuidedDir(run, pass, site.site);
  const GuidedSettings settings{run.options->guided_null_windows,
                                run.options->match.max_false_match,
                                run.options->guided_sigma_floor_m};
  if (const std::optional<GuidedUnitResult> done = FinishedUnitResult<GuidedUnitResult>(run, dir);
      done && SamePrior(done->prior, guided) && done->settings == settings) {
    return *done;
  }
  fs::create_directories(dir);
  const fs::path ortho_path = SiteDir(run, site.site) / "ortho.tif";
  const Orthophoto ortho = ReadOrthophoto(ortho_path);
  const SiteGeoreference georef =
      SiteGeoreference::InMission(run.mission->body, run.mission->origin,
                                  TelemetryTraverseFromSite(run.mission->telemetry[site_index]));
  OrbitalPrior prior{georef.Origin(), georef.body, guided.sigma_m};
  prior.expected_shift_en_m = guided.shift_en_m;
  prior.expected_rotation_rad = guided.rotation_rad;
  OrbitalMatchOptions options = run.options->match;
  options.null_windows = run.options->guided_null_windows;
  GuidedUnitResult summary;
  summary.site = site.site;
  summary.pass = pass;
  summary.prior = PriorRecord(guided);
  summary.settings = settings;
  summary.registration = RegisterSiteOrtho(run, ortho, ortho_path, site.site, prior, options, dir);
  FinishUnit(run, dir, summary.ToJson());
  return summary;
}

}  // namespace mission_run
}  // namespace areomap
