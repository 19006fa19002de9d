// Guided re-registration of a finished `areomap run` against the generated mission's truth, and
// how much its acceptance tests mean in windows this small.
//
// For every site the run re-registered around its adjusted pose (summary.json
// "guided_registration"): the match again with the recorded guided prior, the control points the
// run made from it against the truth, and the same search
// with its centre displaced by 2, 4 and 8 window radii in 8 directions (the true match outside
// the window: whatever is accepted there is a false control point), with the chance-level test
// (OrbitalMatchOptions::null_windows, as the run uses it) and without it (the run's other
// tests only). The truth correction of site k: its true minus telemetry position (east, north)
// and a turn of -(true - telemetry heading) counter-clockwise on the map.
//
// Run: build/ci/bench/areomap_bench_guided_registration MISSION_DIR RUN_DIR
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/site_georeference.h"
#include "areomap/pipeline/mission_run.h"
#include "areomap/registration/orbital_image.h"
#include "areomap/registration/orbital_match.h"
#include "mission_truth.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

using bench::ReadJson;

int Run(const fs::path& mission_dir, const fs::path& run_dir) {
  const MissionManifest mission = bench::ReadMissionWithTruth(mission_dir);
  const OrbitalImage orbital = bench::OpenOrbitalImage(mission);
  const PixelGrid orbital_grid(orbital.geotransform(), orbital.crs_wkt(), orbital.name());
  const json summary = ReadJson(run_dir / "summary.json");
  const MissionRunOptions run_options;  // The defaults `areomap run` used.

  std::printf(
      "site pass sigma[m] radius[px] | matched CC null_max | control points: worst error [m] | "
      "turn error [deg] | "
      "displaced windows accepted: with chance test / without\n");
  int tried = 0, matched = 0, displaced_total = 0, false_with = 0, false_without = 0;
  std::vector<double> errors;
  for (const json& pass : summary.at("guided_registration").at("passes")) {
    for (const json& attempt : pass.at("attempted")) {
      const int site = attempt.at("site").get<int>();
      size_t index = 0;
      while (index < mission.sites.size() && mission.sites[index].site != site) ++index;
      if (index == mission.sites.size()) throw Error("summary.json: unknown site");
      const MissionSitePose& telemetry = mission.telemetry[index];
      const MissionSitePose& truth = mission.truth_sites[index];
      const json& p = attempt.at("prior");
      const std::string folder = bench::SiteFolder(site);
      const fs::path ortho_path = run_dir / "sites" / folder / "ortho.tif";
      const SiteGeoreference georef = bench::TelemetrySiteGeoreference(mission, index);
      const OrthoImage ortho = OrthoImageFromOrthophoto(ReadOrthophoto(ortho_path),
                                                        ortho_path.string(), site, georef.Origin());
      OrbitalPrior prior{georef.Origin(), georef.body, p.at("sigma_m").get<double>()};
      prior.expected_shift_en_m =
          Eigen::Vector2d(p.at("shift_east_m").get<double>(), p.at("shift_north_m").get<double>());
      prior.expected_rotation_rad = p.at("rotation_deg").get<double>() * std::numbers::pi / 180.0;
      OrbitalMatchOptions options = run_options.match;
      options.null_windows = run_options.guided_null_windows;
      const OrbitalMatch m = MatchOrthoToOrbital(ortho, orbital, prior, options);

      // The control points the run made from the guided match against the truth: a point at
      // p in the (believed, north-up) site frame truly lies at T_true + Rz(h_true - h_tel) p
      // in site 0's frame; the control point puts it at its MBF position.
      const json controls =
          ReadJson(run_dir / "guided" / ("pass_" + std::to_string(pass.at("pass").get<int>())) /
                   folder / "control_points.json")
              .at("control_points");
      const Rigid3d site0_from_mbf =
          SiteGeoreference::InMission(mission.body, mission.origin, Rigid3d())
              .mbf_from_site.Inverse();
      const Rigid3d truth_from_site(
          Eigen::Quaterniond(
              Eigen::AngleAxisd(truth.heading - telemetry.heading, Eigen::Vector3d::UnitZ())),
          truth.position);
      double worst = 0.0;
      for (const json& c : controls) {
        const auto in_site = c.at("position_in_site_m").get<std::vector<double>>();
        const auto mbf = c.at("position_mbf_m").get<std::vector<double>>();
        const Eigen::Vector3d expected =
            truth_from_site * Eigen::Vector3d(in_site[0], in_site[1], in_site[2]);
        const Eigen::Vector3d given = site0_from_mbf * Eigen::Vector3d(mbf[0], mbf[1], mbf[2]);
        const double e = (given - expected).head<2>().norm();
        worst = std::max(worst, e);
        errors.push_back(e);
      }
      const double turn_error =
          (m.rotation_rad + (truth.heading - telemetry.heading)) * 180.0 / std::numbers::pi;
      ++tried;
      matched += m.matched ? 1 : 0;

      // Displaced windows.
      int with = 0, without = 0, displaced = 0;
      const double radius_m = options.search_sigmas * prior.sigma_m;
      for (const double times : {2.0, 4.0, 8.0}) {
        for (int k = 0; k < 8; ++k) {
          const double a = k * std::numbers::pi / 4.0;
          OrbitalPrior wrong = prior;
          wrong.expected_shift_en_m += times * radius_m * Eigen::Vector2d(std::cos(a), std::sin(a));
          ++displaced;
          const OrbitalMatch w = MatchOrthoToOrbital(ortho, orbital, wrong, options);
          if (w.matched) {
            ++with;
            std::printf(
                "  accepted %g radii off at %d deg: CC %.3f, ratio %.2f, relative sharpness "
                "%.2f, %d of %d wrong windows reach it (best %.3f); %.2f m from the match\n",
                times, 45 * k, w.correlation, w.peak_ratio, w.relative_sharpness, w.null_reaching,
                w.null_windows, w.null_highest, (w.shift_en_m - m.shift_en_m).norm());
          }
          OrbitalMatchOptions no_chance = options;
          no_chance.null_windows = 0;
          without += MatchOrthoToOrbital(ortho, orbital, wrong, no_chance).matched ? 1 : 0;
        }
      }
      displaced_total += displaced;
      false_with += with;
      false_without += without;
      std::printf(
          "%4d %4d %8.2f %10d | %7s %.3f %.3f | %2zu points: %.3f | %6.2f | %d / %d of %d\n", site,
          pass.at("pass").get<int>(), prior.sigma_m, m.search_radius_px, m.matched ? "yes" : "no",
          m.correlation, m.null_highest, controls.size(), worst, std::remainder(turn_error, 360.0),
          with, without, displaced);
    }
  }
  std::sort(errors.begin(), errors.end());
  std::printf(
      "\n%d sites re-registered, %d matched; %zu control points, horizontal error against the "
      "truth "
      "median %.3f m, worst %.3f m; displaced windows accepted (false control): %d of %d with the "
      "chance test, %d without\n",
      tried, matched, errors.size(), errors.empty() ? 0.0 : errors[errors.size() / 2],
      errors.empty() ? 0.0 : errors.back(), false_with, displaced_total, false_without);
  return 0;
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s MISSION_DIR RUN_DIR\n", argv[0]);
    return 2;
  }
  try {
    return areomap::Run(argv[1], argv[2]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
