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

namespace areomap::mission_run {
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

json PriorJson(const GuidedPrior& prior) {
  return {{"shift_east_m", prior.shift_en_m.x()},
          {"shift_north_m", prior.shift_en_m.y()},
          {"rotation_deg", prior.rotation_rad * 180.0 / std::numbers::pi},
          {"sigma_m", prior.sigma_m}};
}

// Whether a finished unit was guided by (practically) the same prior: 1 mm, 1e-4 degrees.
bool SamePrior(const json& recorded, const GuidedPrior& prior) {
  if (!recorded.is_object()) return false;
  const json now = PriorJson(prior);
  for (const auto& [key, value] : now.items()) {
    const double tolerance = key == "rotation_deg" ? 1e-4 : 1e-3;
    if (!recorded.contains(key) || !recorded[key].is_number() ||
        std::abs(recorded[key].get<double>() - value.get<double>()) > tolerance) {
      return false;
    }
  }
  return true;
}

}  // namespace

GuidedPrior GuidedPriorFromAdjustment(const json& site, double sigma_floor_m) {
  const std::string what = "adjustment.json: site " + std::to_string(site.value("site", -1));
  try {
    const Eigen::Vector3d initial = Vector3(site.at("initial").at("position_m"), what);
    const Eigen::Vector3d adjusted = Vector3(site.at("adjusted").at("position_m"), what);
    const Eigen::Matrix3d turn =
        (Quaternion(site.at("initial").at("rotation_wxyz"), what).inverse() *
         Quaternion(site.at("adjusted").at("rotation_wxyz"), what))
            .toRotationMatrix();
    const auto rows = site.at("covariance").get<std::vector<std::vector<double>>>();
    if (rows.size() != 6 || rows[3].size() != 6 || rows[4].size() != 6) {
      throw Error(what + ": expected a 6 x 6 \"covariance\"");
    }
    // Site frames: x north, y east, z down; the pose covariance is (rotation, translation).
    Eigen::Matrix2d horizontal;
    horizontal << rows[3][3], rows[3][4], rows[4][3], rows[4][4];
    const double largest =
        Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d>(horizontal, Eigen::EigenvaluesOnly)
            .eigenvalues()
            .maxCoeff();
    GuidedPrior prior;
    prior.shift_en_m = Eigen::Vector2d(adjusted.y() - initial.y(), adjusted.x() - initial.x());
    // A turn from north towards east (about z down) is clockwise on the map.
    prior.rotation_rad = -std::atan2(turn(1, 0), turn(0, 0));
    prior.sigma_m = std::max(sigma_floor_m, std::sqrt(std::max(largest, 0.0)));
    if (!prior.shift_en_m.allFinite() || !std::isfinite(prior.sigma_m)) {
      throw Error(what + ": the adjusted pose or covariance is not finite");
    }
    return prior;
  } catch (const json::exception& e) {
    throw Error(what + ": expected initial/adjusted position_m, rotation_wxyz and covariance (" +
                e.what() + ")");
  }
}

fs::path GuidedDir(const RunContext& run, int pass, int site) {
  return run.out_dir / "guided" / ("pass_" + std::to_string(pass)) / ("site_" + ThreeDigits(site));
}

json RunGuidedRegistrationUnit(const RunContext& run, size_t site_index, int pass,
                               const GuidedPrior& guided) {
  const MissionSite& site = run.mission->sites.at(site_index);
  const fs::path dir = GuidedDir(run, pass, site.site);
  const json settings = {{"null_windows", run.options->guided_null_windows},
                         {"max_null_fraction", run.options->match.max_null_fraction},
                         {"sigma_floor_m", run.options->guided_sigma_floor_m}};
  if (const json done = FinishedUnit(run, dir); done.is_object() &&
                                                SamePrior(done.value("prior", json()), guided) &&
                                                done.value("settings", json()) == settings) {
    return done;
  }
  fs::create_directories(dir);
  const fs::path ortho_path = SiteDir(run, site.site) / "ortho.tif";
  const Orthophoto ortho = ReadOrthophoto(ortho_path);
  const SiteGeoreference georef =
      SiteGeoreference::InMission(run.mission->body, run.mission->origin,
                                  TelemetryTraverseFromSite(run.mission->telemetry[site_index]));
  OrbitalPrior prior{georef.Origin(), guided.sigma_m};
  prior.expected_shift_en_m = guided.shift_en_m;
  prior.expected_rotation_rad = guided.rotation_rad;
  OrbitalMatchOptions options = run.options->match;
  options.null_windows = run.options->guided_null_windows;
  const json registration =
      RegisterSiteOrtho(run, ortho, ortho_path, site.site, prior, options, dir);
  const json summary = {{"site", site.site},
                        {"pass", pass},
                        {"prior", PriorJson(guided)},
                        {"settings", settings},
                        {"registration", registration}};
  FinishUnit(run, dir, summary);
  return summary;
}

}  // namespace areomap::mission_run
