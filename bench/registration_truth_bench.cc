// The orbital registrations of a finished `areomap run` against the generated mission's truth,
// in units of their own sigmas, by peak correlation.
//
// Every confident match the run made (each site's first pass, and each guided pass recorded in
// summary.json "guided_registration") is made again with the current code: the site's
// ortho.tif, the prior the run used and `areomap run`'s default match options. So a change to
// the reported sigmas is measured on a kept run without running the mission again. The truth
// correction of site k: its true minus telemetry position (east, north) and a turn of -(true -
// telemetry heading) counter-clockwise on the map (as in guided_registration_bench.cc).
//
// Run: build/ci/bench/areomap_bench_registration_truth [--rotation-floor-correlation R]
//          MISSION_DIR RUN_DIR [MISSION_DIR RUN_DIR ...]
// (R = 0.01 gives the constant rotation floor of before 2026-12-04.)
#include <cmath>
#include <cstdio>
#include <filesystem>
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

// One match against the truth.
struct Outcome {
  double correlation = 0.0;
  double rotation_error_deg = 0.0;
  double rotation_z = 0.0;  // Rotation error / its sigma.
  Eigen::Vector2d shift_error_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d shift_z = Eigen::Vector2d::Zero();  // Per axis, error / sigma.
};

struct Band {
  double low = 0.0, high = 0.0;
  int count = 0;
  double sum_sq_rotation_deg = 0.0, sum_sq_rotation_z = 0.0, sum_sq_shift_m = 0.0,
         sum_sq_shift_z = 0.0;
  int rotation_within_1_sigma = 0, shift_axes_within_1_sigma = 0;

  void Add(const Outcome& o) {
    ++count;
    sum_sq_rotation_deg += o.rotation_error_deg * o.rotation_error_deg;
    sum_sq_rotation_z += o.rotation_z * o.rotation_z;
    sum_sq_shift_m += o.shift_error_m.squaredNorm();
    sum_sq_shift_z += o.shift_z.squaredNorm();
    rotation_within_1_sigma += std::abs(o.rotation_z) <= 1.0;
    shift_axes_within_1_sigma += static_cast<int>((o.shift_z.array().abs() <= 1.0).count());
  }
  void Print() const {
    if (count == 0) {
      std::printf("CC [%.2f, %.2f): none\n", low, high);
      return;
    }
    std::printf(
        "CC [%.2f, %.2f): %2d matches | rotation error RMS %.3f deg, mean z^2 %.2f, within 1 "
        "sigma %d | rover error RMS %.3f m, mean z^2 per axis %.2f, axes within 1 sigma %d / %d\n",
        low, high, count, std::sqrt(sum_sq_rotation_deg / count), sum_sq_rotation_z / count,
        rotation_within_1_sigma, std::sqrt(sum_sq_shift_m / count), sum_sq_shift_z / (2 * count),
        shift_axes_within_1_sigma, 2 * count);
  }
};

Outcome Judge(const OrbitalMatch& m, const MissionSitePose& telemetry,
              const MissionSitePose& truth) {
  Outcome o;
  o.correlation = m.correlation;
  // Positions are north, east, down in site 0's frame; the correction is east, north.
  const Eigen::Vector3d d = truth.position - telemetry.position;
  o.shift_error_m = m.shift_en_m - Eigen::Vector2d(d.y(), d.x());
  for (int axis = 0; axis < 2; ++axis) {
    o.shift_z(axis) = o.shift_error_m(axis) / std::sqrt(m.shift_covariance_en_m2(axis, axis));
  }
  if (m.rotation_solved) {
    o.rotation_error_deg =
        std::remainder(DegFromRad(m.rotation_rad + (truth.heading - telemetry.heading)), 360.0);
    o.rotation_z = o.rotation_error_deg / DegFromRad(m.rotation_sigma_rad);
  }
  return o;
}

void Run(const fs::path& mission_dir, const fs::path& run_dir,
         const OrbitalMatchOptions& match_options, std::vector<Band>& bands) {
  const MissionManifest mission = bench::ReadMissionWithTruth(mission_dir);
  const OrbitalImage orbital = bench::OpenOrbitalImage(mission);
  const json summary = ReadJson(run_dir / "summary.json");
  const MissionRunOptions run_options;  // The defaults `areomap run` used (guided windows).

  // (site index, pass, prior) of every confident match of the run.
  struct Attempt {
    size_t index;
    int pass;
    OrbitalPrior prior;
  };
  std::vector<Attempt> attempts;
  const auto index_of = [&](int site) {
    for (size_t i = 0; i < mission.sites.size(); ++i) {
      if (mission.sites[i].site == site) return i;
    }
    throw Error((run_dir / "summary.json").string() + ": unknown site " + std::to_string(site));
  };
  for (size_t i = 0; i < mission.sites.size(); ++i) {
    const json r = ReadJson(run_dir / "sites" / bench::SiteFolder(mission.sites[i].site) /
                            "registration.json");
    if (!r.value("matched", false)) continue;
    const SiteGeoreference georef = bench::TelemetrySiteGeoreference(mission, i);
    attempts.push_back(
        {i, 0, OrbitalPrior{georef.Origin(), georef.body, r.at("prior_sigma_m").get<double>()}});
  }
  for (const json& pass : summary.at("guided_registration").at("passes")) {
    for (const json& attempt : pass.at("attempted")) {
      if (!attempt.value("matched", false)) continue;
      const size_t i = index_of(attempt.at("site").get<int>());
      const json& p = attempt.at("prior");
      const SiteGeoreference georef = bench::TelemetrySiteGeoreference(mission, i);
      OrbitalPrior prior{georef.Origin(), georef.body, p.at("sigma_m").get<double>()};
      prior.expected_shift_en_m =
          Eigen::Vector2d(p.at("shift_east_m").get<double>(), p.at("shift_north_m").get<double>());
      prior.expected_rotation_rad = RadFromDeg(p.at("rotation_deg").get<double>());
      attempts.push_back({i, pass.at("pass").get<int>(), prior});
    }
  }

  std::printf(
      "%s\n site pass   CC   | rotation error, sigma, z [deg] | rover error E N [m], z E N | "
      "template px, peak ratio, relative sharpness\n",
      run_dir.string().c_str());
  for (const Attempt& a : attempts) {
    const fs::path ortho_path =
        run_dir / "sites" / bench::SiteFolder(mission.sites[a.index].site) / "ortho.tif";
    const OrthoImage ortho =
        OrthoImageFromOrthophoto(ReadOrthophoto(ortho_path), ortho_path.string(),
                                 mission.sites[a.index].site, a.prior.position);
    OrbitalMatchOptions options = match_options;
    if (a.pass > 0) options.null_windows = run_options.guided_null_windows;
    const OrbitalMatch m = MatchOrthoToOrbital(ortho, orbital, a.prior, options);
    if (!m.matched) {
      std::printf("%5d %4d   not matched again: %s\n", mission.sites[a.index].site, a.pass,
                  m.reason.c_str());
      continue;
    }
    const Outcome o = Judge(m, mission.telemetry[a.index], mission.truth_sites[a.index]);
    std::printf(
        "%5d %4d  %.3f | %+6.2f %5.2f %+6.1f | %+6.3f %+6.3f  %+5.1f %+5.1f | %6d %5.2f %4.2f\n",
        mission.sites[a.index].site, a.pass, o.correlation, o.rotation_error_deg,
        DegFromRad(m.rotation_sigma_rad), o.rotation_z, o.shift_error_m.x(), o.shift_error_m.y(),
        o.shift_z.x(), o.shift_z.y(), m.template_pixels, m.peak_ratio, m.relative_sharpness);
    for (Band& band : bands) {
      if (o.correlation >= band.low && o.correlation < band.high) band.Add(o);
    }
  }
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  areomap::OrbitalMatchOptions options = areomap::MissionRunOptions().match;
  if (args.size() >= 2 && args[0] == "--rotation-floor-correlation") {
    options.rotation_floor_correlation = std::stod(args[1]);
    args.erase(args.begin(), args.begin() + 2);
  }
  if (args.empty() || args.size() % 2 != 0) {
    std::fprintf(stderr,
                 "usage: %s [--rotation-floor-correlation R] MISSION_DIR RUN_DIR [MISSION_DIR "
                 "RUN_DIR ...]\n",
                 argv[0]);
    return 2;
  }
  try {
    options.Check();
    std::vector<areomap::Band> bands = {
        {0.0, 0.5}, {0.5, 0.55}, {0.55, 0.7}, {0.7, 1.01}, {0.0, 1.01}};
    for (size_t k = 0; k < args.size(); k += 2) {
      areomap::Run(args[k], args[k + 1], options, bands);
    }
    for (const areomap::Band& band : bands) band.Print();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
  return 0;
}
