// areomap simulate --preset demo|long --seed N --out DIR: writes a synthetic mission.
#include <iostream>

#include "areomap/samples/mission.h"
#include "commands.h"

namespace areomap::cli {

// What `areomap simulate --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kSimulateDetails =
    "Generates a synthetic mission with known truth: fractal terrain, fresh craters (bowl or flat\n"
    "floor, raised rim), rocks (hemispheroid, semi-ellipsoid, cone, tetrahedron; Golombek–Rapp\n"
    "size–frequency, k = 0.05 of the Gusev plains or `--rock-abundance K`) along the traverse, a\n"
    "HiRISE-like orthoimage (Lambertian shading, cast shadows, MTF, noise, 10-bit) and DTM, a\n"
    "traverse with telemetry errors (5 % leg scale, 2° heading drift per leg by default), a "
    "Navcam\n"
    "stereo panorama per site (`--navcam-pairs`, `--navcam-fov`), optionally a Pancam one\n"
    "(`--pancam-pairs 22`: ~4x more precise stereo, which takes 20–25 m legs from 3 to 12 of 12\n"
    "with rock tie points, docs/rocks.md) and the truth files. `long` is a ~1.1 km, 46-site\n"
    "traverse with a second-sun image and a CTX-like 6 m image.\n"
    "`--lat/--lon/--sites/--min-leg/--max-leg` override the preset.";

namespace {

// The preset and what the options override in it (unset: the preset's value).
struct SimulateCommandOptions {
  std::string preset = "demo";
  uint32_t seed = 1;
  std::string out;
  std::optional<double> lat, lon;
  std::optional<int> sites;
  std::optional<double> min_leg, max_leg;
  std::optional<int> pairs, pancam_pairs;
  std::string landing_site = "gusev";
  bool second_sun = false, ctx = false;
  std::optional<double> fov;
  std::optional<double> rock_abundance;
};

void AddSimulateOptions(CLI::App* cmd, SimulateCommandOptions& o) {
  cmd->add_option("--preset", o.preset, "demo (small, ~1 min) or long (~1.1 km traverse)")
      ->capture_default_str();
  cmd->add_option("--seed", o.seed, "Seed of every random choice")
      ->check(IntegerIn(0, 4294967295))  // 32 bits
      ->capture_default_str();
  cmd->add_option("--out", o.out, "Mission folder (created if needed)")->required();
  auto* site = cmd->add_option_group("Site and traverse");
  site->add_option("--landing-site", o.landing_site, "gusev (Spirit) or meridiani (Opportunity)")
      ->capture_default_str();
  site->add_option("--lat", o.lat, "Planetocentric latitude of site 0 [deg] (overrides)")
      ->check(NumberIn(-80.0, 80.0, Bound::kOpen, Bound::kOpen));
  site->add_option("--lon", o.lon, "East longitude of site 0 [deg]")->check(Longitude());
  site->add_option("--sites", o.sites, "Number of sites")->check(IntegerIn(1, 1000));
  site->add_option("--min-leg", o.min_leg, "Shortest leg [m]")->check(PositiveNumber());
  site->add_option("--max-leg", o.max_leg, "Longest leg [m] (at least the shortest)")
      ->check(PositiveNumber());
  site->add_option("--rock-abundance", o.rock_abundance,
                   "Golombek-Rapp k: fraction of the ground covered by rocks (0.05, the Gusev "
                   "plains; 0.1-0.2 rockier fields)")
      ->check(NumberIn(0.0, 1.0, Bound::kOpen, Bound::kOpen));
  auto* rover = cmd->add_option_group("Rover cameras");
  rover->add_option("--navcam-pairs", o.pairs, "Navcam stereo pairs per site (0: no images)")
      ->check(IntegerIn(0, 64));
  rover
      ->add_option("--navcam-fov", o.fov,
                   "Navcam horizontal field of view [deg] (45.4; 0: from the focal length)")
      ->check(NumberIn(0.0, 180.0, Bound::kClosed, Bound::kOpen));
  rover->add_option("--pancam-pairs", o.pancam_pairs, "Pancam stereo pairs per site (0)")
      ->check(IntegerIn(0, 64));
  auto* orbital = cmd->add_option_group("Orbital products");
  orbital->add_flag("--second-sun", o.second_sun, "Also an orthoimage under another sun");
  orbital->add_flag("--ctx", o.ctx, "Also a CTX-like 6 m image");
}

// The preset with the options' overrides applied, checked.
MissionOptions SimulateMissionOptions(const SimulateCommandOptions& o) {
  MissionOptions options = MissionOptions::Preset(o.preset);
  options.seed = o.seed;
  std::tie(options.site_lat_deg, options.site_lon_deg) = LandingSite(o.landing_site);
  options.second_sun_image = options.second_sun_image || o.second_sun;
  options.ctx_image = options.ctx_image || o.ctx;
  if (o.pancam_pairs) options.pancam_pairs = *o.pancam_pairs;
  if (o.lat) options.site_lat_deg = *o.lat;
  if (o.lon) options.site_lon_deg = *o.lon;
  if (o.sites) options.traverse.site_count = *o.sites;
  if (o.min_leg) options.traverse.min_leg_m = *o.min_leg;
  if (o.max_leg) options.traverse.max_leg_m = *o.max_leg;
  if (o.pairs) options.navcam_pairs = *o.pairs;
  if (o.fov) options.navcam.field_of_view_deg = *o.fov;
  if (o.rock_abundance) options.scene.rock_abundance_k = *o.rock_abundance;
  options.Check();
  return options;
}

nlohmann::json SimulateSummaryJson(const MissionOptions& options, const MissionSummary& summary) {
  return {{"command", "simulate"},
          {"preset", options.preset},
          {"seed", options.seed},
          {"manifest", "mission.json"},
          {"sites", summary.site_count},
          {"craters", summary.crater_count},
          {"rocks", summary.rock_count},
          {"rock_abundance_k", options.scene.rock_abundance_k},
          {"traverse_length_m", summary.traverse_length_m},
          {"final_telemetry_error_m", summary.final_telemetry_error_m},
          {"orbital_size_px", summary.orbital_size_px},
          {"rover_images", summary.rover_images}};
}

void RunSimulateCommand(const SimulateCommandOptions& o, const GlobalOptions& global) {
  const MissionOptions options = SimulateMissionOptions(o);
  // Staged: the whole mission folder is replaced at once; a failed run leaves the earlier one.
  OutputFolder out(
      o.out, OutputPolicy(global, "simulate",
                          {"mission.json", "sites/", "orbital/", "truth/", "telemetry/"}, {}));
  const MissionSummary summary =
      GenerateMission(options, out.dir(), MakeProgressBar(global, "simulate"));
  WriteSummary(out.dir(), SimulateSummaryJson(options, summary));
  out.Commit();
  if (!global.quiet) {
    std::cout << "mission " << o.out << ": " << summary.site_count << " sites over "
              << summary.traverse_length_m << " m (telemetry off by "
              << summary.final_telemetry_error_m << " m at the end), " << summary.crater_count
              << " craters, " << summary.rock_count << " rocks, orbital image "
              << summary.orbital_size_px << " px square, " << summary.rover_images
              << " rover images\n";
  }
}

}  // namespace

void AddSimulateCommand(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<SimulateCommandOptions>();
  auto* cmd = app.add_subcommand(
      "simulate",
      "Generate a synthetic mission with known truth: terrain with craters and rocks, HiRISE-like "
      "orthoimage and DTM, a rover traverse with telemetry errors (docs/mission-format.md)");
  cmd->footer(kSimulateDetails);
  AddSimulateOptions(cmd, *o);
  cmd->callback([o, &global] { RunSimulateCommand(*o, global); });
}

}  // namespace areomap::cli
