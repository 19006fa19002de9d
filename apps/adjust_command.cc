// areomap adjust NETWORK.json [MORE.json ...] --out DIR: bundle adjustment of a rover traverse
// from tie points, control points, pose priors and heights (docs/adjustment-format.md).
#include <iostream>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/adjustment/traverse_adjustment.h"
#include "commands.h"

namespace areomap::cli {

// What `areomap adjust --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kAdjustDetails =
    "Bundle adjustment of a rover traverse (Ceres): site poses and landmarks from stereo or pixel\n"
    "tie points, orbital control points, telemetry/VO pose priors and DTM heights, each with its\n"
    "own covariance; Huber loss, normalized residual tests (rejections with reasons), 6×6\n"
    "covariance per site; `--rock-tie-variance-factor` scales the rock tie points' covariances.\n"
    "Writes the traverse in the site frame, MBF and lat/lon/h with 1σ ellipses (CSV, GeoPackage), "
    "a\n"
    "per-leg RE table, a traverse map over the orbital image, `adjustment.json` and `report.txt`.\n"
    "Input format: docs/adjustment-format.md.";

void AddAdjustCommand(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::vector<std::string> inputs;
    std::string out;
    std::string orbital;
    TraverseAdjustmentOptions adjustment;
  };
  auto o = std::make_shared<Options>();
  auto* cmd = app.add_subcommand(
      "adjust",
      "Bundle-adjust a rover traverse (site poses from tie points, orbital control points, pose "
      "priors, heights) and anchor it in Mars body-fixed coordinates with 1-sigma ellipses");
  cmd->footer(kAdjustDetails);
  cmd->add_option("inputs", o->inputs,
                  "Adjustment input JSON files, merged in order (docs/adjustment-format.md)")
      ->required();
  cmd->add_option("--out", o->out, "Output folder (created if needed)")->required();
  cmd->add_option("--orbital", o->orbital,
                  "Georeferenced orbital image to draw the traverse map on (traverse_map.png)");
  BundleOptions& bundle = o->adjustment.bundle;
  cmd->add_option("--huber", bundle.huber_scale,
                  "Huber scale on each observation's Mahalanobis "
                  "distance [sigmas]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--alpha", bundle.rejection_alpha,
                  "Significance of the normalized residual test for rejecting observations")
      ->check(NumberIn(0.0, 0.5, Bound::kOpen, Bound::kOpen))
      ->capture_default_str();
  cmd->add_option("--rejection-rounds", bundle.max_rejection_rounds,
                  "Most re-solves after rejecting observations")
      ->check(IntegerAtLeast(0))
      ->capture_default_str();
  cmd->add_option("--rock-tie-variance-factor", o->adjustment.rock_tie_variance_factor,
                  "Multiplies the rock tie points' covariances (e.g. by a run's pooled sigma0^2, "
                  "summary.json rock_tie_variance, which the run itself reports only)")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--ellipse-scale", o->adjustment.map.ellipse_scale,
                  "Exaggeration of the 1-sigma ellipses on the traverse map")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->callback([o, &global] {
    o->adjustment.orbital_image = o->orbital;
    o->adjustment.Check();
    std::vector<std::filesystem::path> inputs(o->inputs.begin(), o->inputs.end());
    inputs.push_back(o->orbital);
    // Staged: an adjustment that fails (at the GeoPackage, say) leaves the earlier one whole.
    OutputFolder out(o->out, OutputPolicy(global, "adjust",
                                          {"adjustment.json", "report.txt", "sites.csv", "legs.csv",
                                           "traverse.gpkg", "traverse_map.png"},
                                          inputs));
    BundleInputFile input = ReadBundleInput({o->inputs.begin(), o->inputs.end()});
    nlohmann::json summary = AdjustTraverseInput(std::move(input), out.dir(), o->adjustment,
                                                 MakeProgressBar(global, "adjust"));
    summary["command"] = "adjust";
    WriteSummary(out.dir(), summary);
    out.Commit();
    if (!global.quiet) {
      std::cout << "adjusted " << summary["sites"] << " sites (" << summary["tie_points"]
                << " tie points, " << summary["control_points"] << " control points, "
                << summary["rejected"] << " observations rejected), sigma0 "
                << summary["sigma0"].get<double>() << "; largest 1-sigma ellipse "
                << summary["largest_horizontal_sigma_m"].get<double>() << " m";
      if (summary.contains("adjusted_end_error_m")) {
        std::cout << "; end-point error " << summary["initial_end_error_m"].get<double>()
                  << " m -> " << summary["adjusted_end_error_m"].get<double>() << " m";
      }
      if (summary["sites_with_priors_only"].get<int>() > 0) {
        std::cout << "\nwarning: " << summary["sites_with_priors_only"]
                  << " sites have no tie point, control point or height (priors only)";
      }
      std::cout << "\nreport: " << (std::filesystem::path(o->out) / "report.txt").string() << "\n";
    }
  });
}

}  // namespace areomap::cli
