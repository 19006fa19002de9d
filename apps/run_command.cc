// areomap run MISSION --out DIR: the end-to-end job on a mission folder (mission_run.h), then the
// HTML report; areomap report DIR re-writes the report from a finished run's folder.
#include <cstdio>
#include <iostream>
#include <limits>
#include <sstream>

#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/pipeline/mission_plan.h"
#include "areomap/pipeline/mission_run.h"
#include "areomap/pipeline/run_report.h"
#include "areomap/pipeline/run_summary.h"
#include "commands.h"
#include "run_options.h"

namespace areomap::cli {
namespace {

namespace fs = std::filesystem;

// A figure of the run's summary; NaN (printed "nan") where it is missing: undefined, as the
// precision of no detections.
double Number(const OptionalNumber& value) {
  return value.value_or(std::numeric_limits<double>::quiet_NaN());
}

// The per-site and per-leg lines.
void PrintSitesAndLegs(const RunSummary& s) {
  for (const mission_run::SiteUnitResult& site : s.sites) {
    const mission_run::SiteRegistrationResult& r = site.registration;
    char verdict[96];
    if (r.matched) {
      std::snprintf(verdict, sizeof(verdict), "matched, CC %.3f", Number(r.correlation));
    } else {
      std::snprintf(verdict, sizeof(verdict), "no match: %s", r.reason.c_str());
    }
    std::printf("site %3d: %8d points, registration %s\n", site.site, static_cast<int>(site.points),
                verdict);
  }
  for (const mission_run::LegUnitResult& leg : s.legs) {
    const mission_run::LegPassRecord& match = leg.match;
    std::printf("leg %3d -> %3d: %-30s %3d tie points", leg.site_a, leg.site_b,
                match.outcome.c_str(), static_cast<int>(match.tie_points));
    if (leg.first_pass && leg.first_pass->outcome != match.outcome) {
      std::printf(" (first pass: %s)", leg.first_pass->outcome.c_str());
    }
    if (mission_run::Known(match.relative_error_percent)) {
      std::printf(", RE %.2f %%", Number(match.relative_error_percent));
    }
    if (leg.leg_test && leg.leg_test->tested && !leg.leg_test->dropped.empty()) {
      std::printf(" (legs' test: F %.2f > %.2f, dropped %zu)", leg.leg_test->first_f_statistic,
                  leg.leg_test->f_threshold, leg.leg_test->dropped.size());
    }
    std::printf("\n");
  }
}

// The lines a person reads after a run: per-leg outcome and RE, and the final errors.
void PrintRunSummary(const RunSummary& s) {
  const UnitsSummary units = s.units.value_or(UnitsSummary{});
  std::printf(
      "sites: %d computed, %d reused; legs: %d computed, %d reused, %d matched again (%.0f s)\n",
      units.sites_computed, units.sites_reused, units.legs_computed, units.legs_reused,
      units.legs_rematched, Number(s.seconds));
  PrintSitesAndLegs(s);
  const mission_run::TieVarianceRecord ties =
      s.tie_variance.value_or(mission_run::TieVarianceRecord{});
  if (ties.sigma0_squared) {
    std::printf(
        "rock tie fits of %d legs: pooled sigma0^2 %.3f (95 %% upper bound %.3f, redundancy %d)\n",
        static_cast<int>(ties.legs), Number(ties.sigma0_squared),
        Number(ties.sigma0_squared_upper_95), static_cast<int>(ties.redundancy));
  }
  if (ties.applied_factor) {
    std::printf("legs matched again with the rock ties' variance factor %.3f (second pass)\n",
                Number(ties.applied_factor));
  }
  const std::vector<mission_run::GuidedPassRecord> no_passes;
  for (const mission_run::GuidedPassRecord& pass : s.guided ? s.guided->passes : no_passes) {
    std::printf(
        "guided registration pass %d (around the adjusted poses, %zu sites tried): %zu more",
        pass.pass, pass.attempted.size(), pass.registered.size());
    for (int site : pass.registered) std::printf(" %d", site);
    if (!pass.replaced.empty()) {
      std::printf("; re-matched (first turn at the rotation search's edge):");
      for (int site : pass.replaced) std::printf(" %d", site);
    }
    std::printf("\n");
  }
  const mission_run::AdjustmentResult a = s.adjustment.value_or(mission_run::AdjustmentResult{});
  std::printf("bundle adjustment: %d tie points, %d control points, %d rejected, sigma0 %.3f\n",
              static_cast<int>(a.tie_points), static_cast<int>(a.control_points),
              static_cast<int>(a.rejected), a.sigma0);
  if (mission_run::Known(a.adjusted_end_error_m)) {
    std::printf("end-point error against truth over %.1f m: telemetry %.2f m, adjusted %.2f m\n",
                Number(a.length_m), Number(a.initial_end_error_m), Number(a.adjusted_end_error_m));
  }
  if (mission_run::Known(a.median_adjusted_error_m)) {
    std::printf(
        "adjusted horizontal error against truth: median %.3f m, worst %.3f m; %d of %d "
        "sites within their 1-sigma ellipse's semi-major axis\n",
        Number(a.median_adjusted_error_m), Number(a.worst_adjusted_error_m),
        static_cast<int>(a.sites_within_1sigma.value_or(0)), a.sites);
  }
  if (s.craters && !s.craters->skipped) {
    std::printf("craters on the orbital image: %d", static_cast<int>(s.craters->craters));
    if (const std::optional<mission_run::CraterScoreRecord>& score = s.craters->score) {
      // Precision is undefined (null) when nothing was detected.
      std::printf(" (truth %d: precision %.2f, recall %.2f)", static_cast<int>(score->truth),
                  Number(score->precision), Number(score->recall));
    }
    std::printf("\n");
  }
  if (s.products && s.products->dtm_minus_orbital_adjusted) {
    const mission_run::TraverseDifference& adjusted = *s.products->dtm_minus_orbital_adjusted;
    const mission_run::TraverseDifference telemetry =
        s.products->dtm_minus_orbital_telemetry.value_or(mission_run::TraverseDifference{});
    std::printf(
        "traverse DTM - orbital DTM over %d cells: RMS %.3f m with telemetry poses, %.3f m "
        "adjusted (products/traverse_dtm.tif, traverse_ortho.tif)\n",
        static_cast<int>(adjusted.cells), Number(telemetry.rms_m), Number(adjusted.rms_m));
  }
  const auto stage = [&](const char* name) {
    const auto it = s.stage_seconds.find(name);
    return it == s.stage_seconds.end() ? std::numeric_limits<double>::quiet_NaN() : it->second;
  };
  std::printf(
      "time: sites %.0f s, legs %.0f s, craters %.0f s, adjustment %.0f s, products %.0f s\n",
      stage("sites"), stage("legs"), stage("craters"), stage("adjustment"), stage("products"));
}

}  // namespace

// What `areomap run --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kRunDetails =
    "The end-to-end job on a mission folder: per site dense stereo (`points.ply`; where a more\n"
    "precise pair, e.g. Pancam over Navcam, sees the same ground only its points are kept,\n"
    "`--keep-coarse-points` keeps all; each pair's points are kept 2 cm apart on the ground, 1 cm\n"
    "for pairs whose pixels are finer than 0.5 mrad such as Pancam: `--point-spacing`,\n"
    "`--fine-point-spacing`, `--fine-pair-ifov`), DTM and orthophoto GeoTIFFs and the "
    "orthophoto's\n"
    "registration onto the orbital image (control points); per leg rock extraction, cross-site\n"
    "matching and the Table 4.5 fault report (tie points; `--rock-min-height` sets the height "
    "rule,\n"
    "12 cm of measured height for Table 4.5's 15 cm of rock; rock pairs compared by their "
    "measured\n"
    "heights, `--compare-models` by their models' eq. 3.28 with `--min-shape-points`;\n"
    "`--low-pair-height`, 16 cm: a pair of rocks both lower is matched only between precise "
    "peaks,\n"
    "unless the global pattern vouches for it: its translation within `--pattern-vouch` (0.2 m) "
    "of\n"
    "the pattern's with `--pattern-vouch-votes` (3) votes, which also overrides the pair cost and\n"
    "rules out as alternatives the neighbours that would put the translation off the pattern; the\n"
    "pattern is fitted as a translation and a turn, the prior's heading error as the rocks "
    "measure\n"
    "it; docs/rocks.md), with the legs' conformal-fit residuals pooled into the rock ties'\n"
    "a-posteriori σ0² (summary.json `rock_tie_variance`: how pessimistic the stereo covariances\n"
    "are), then a second pass that matches every leg again with the tie covariances scaled by "
    "that\n"
    "factor's 95 % upper bound, so that fault detection (RE, the outlier test) judges the ties by\n"
    "the precision the run's own legs show (`applied_factor`; a leg's first pass stays in its\n"
    "`unit.json` `first_pass`; needs a pooled redundancy of 20; `--no-rock-variance-pass`; the\n"
    "adjustment keeps the a-priori covariances), and the legs tested against each other (an F "
    "test\n"
    "of each leg's fit against the other legs' precision: a leg that fails loses its worst tie\n"
    "points or is excluded, summary.json `legs[].leg_test`, `adjustment/rock_ties/`;\n"
    "`--no-leg-test`, `--leg-test-alpha`, docs/rocks.md); craters on the orbital image "
    "(`craters/`:\n"
    "CSV, GeoPackage, overlay PNG, scored against `truth/craters.csv` when present); then the\n"
    "bundle adjustment and anchored traverse (`adjustment/`: CSV, GeoPackage, traverse map), "
    "after\n"
    "which sites that did not register are matched again around their adjusted pose, in a window "
    "of\n"
    "3× their adjusted 1σ with a chance-level test, and the adjustment repeated (`guided/`,\n"
    "summary.json `guided_registration`); the whole traverse's DTM and orthomosaic re-made with "
    "the\n"
    "adjusted poses (`products/traverse_dtm.tif`, `traverse_ortho.tif`, with their RMS against "
    "the\n"
    "orbital DTM for telemetry and adjusted poses); `report.html`; the wall time of each stage in\n"
    "`summary.json` (`stage_seconds`). Every file the manifest names is checked before work "
    "starts;\n"
    "finished sites and legs are reused when the run is repeated or resumed after an "
    "interruption,\n"
    "as long as no file the manifest names has changed (size or modification time; any change\n"
    "reruns every site and leg). A unit one of whose files was deleted (a site's `points.ply`)\n"
    "runs again.";

// What `areomap report --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kReportDetails =
    "Re-writes `DIR/report.html` (one self-contained page: key figures, traverse map, sites and\n"
    "legs tables, registration details, fault-detection tables) from a run folder.";

// The mission options of `run`, kept apart from the folder and executor options so that a plan
// can record them as given (ArgumentsGiven) and `run-unit` read them again (run_options.h).
void AddMissionRunOptions(CLI::App* run, MissionRunArguments* o) {
  // Beyond the stereo's nearest range, which run does not change.
  std::ostringstream max_range_help;
  max_range_help << "Stereo points beyond are dropped [m] (more than the nearest range searched, "
                 << o->run.stereo.min_range_m << " m)";
  run->add_option("--max-range", o->run.stereo.max_range_m, max_range_help.str())
      ->check(NumberAbove(o->run.stereo.min_range_m))
      ->capture_default_str();
  run->add_option("--point-spacing", o->run.point_spacing_m,
                  "Stereo points kept about this far apart on the ground, per pair [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  run->add_option("--fine-point-spacing", o->run.fine_pair_point_spacing_m,
                  "The same for pairs with pixels finer than --fine-pair-ifov (Pancam) [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  run->add_option("--fine-pair-ifov", o->run.fine_pair_max_ifov_mrad,
                  "Angular resolution below which a pair is fine [mrad/px]; 0: none")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  run->add_option("--posting", o->run.dtm.posting_m, "Site DTM and orthophoto posting [m]")
      ->check(NumberIn(0.0, 100.0, Bound::kOpen))
      ->capture_default_str();
  run->add_option("--prior-sigma-per-m", o->run.prior_sigma_per_m,
                  "Orbital search prior: telemetry sigma per metre driven")
      ->check(NumberIn(0.0, 1.0))
      ->capture_default_str();
  run->add_option("--traverse-posting", o->run.traverse_posting_m,
                  "Whole-traverse DTM and orthomosaic posting [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  run->add_option("--crater-min-diameter", o->run.crater_min_diameter_m,
                  "Smallest crater rim diameter on the orbital image [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  run->add_option("--rock-min-height", o->run.matching.fault_detection.min_peak_to_plane_m,
                  "Table 4.5's height rule: rocks whose measured peak-to-plane distance is lower "
                  "are neither modeled nor tie points [m] (measured heights run 2-6 cm under the "
                  "true ones: 0.12 keeps Table 4.5's 15 cm rocks, docs/rocks.md)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  AddRockPairOptions(run, &o->run.matching);
  run->add_flag("--keep-coarse-points", o->keep_coarse_points,
                "Keep every pair's points where a more precise pair (Pancam over Navcam) sees the "
                "same ground");
  run->add_flag("--no-rock-variance-pass", o->no_rock_variance_pass,
                "Accept legs by the rock ties' a-priori covariances only, without matching them "
                "again with the variance factor their first pass shows (the adjustment always "
                "uses the a-priori covariances)");
  run->add_flag("--no-leg-test", o->no_leg_test,
                "Keep every leg's tie points as its fault detection accepted them, without testing "
                "the legs' precision against each other");
  run->add_option("--leg-test-alpha", o->run.leg_test_alpha,
                  "False alarm rate of the legs' F test against each other")
      ->check(NumberIn(1e-9, 0.5))
      ->capture_default_str();
  run->add_flag("--no-craters", o->no_craters, "Skip crater detection on the orbital image");
  run->add_flag("--no-products", o->no_products,
                "Skip the whole-traverse DTM and orthomosaic (products/)");
}

MissionRunOptions MissionRunArguments::Resolve() const {
  MissionRunOptions options = run;
  if (no_craters) options.detect_craters = false;
  if (no_products) options.traverse_products = false;
  if (keep_coarse_points) options.prefer_precise_pairs = false;
  if (no_leg_test) options.leg_test = false;
  if (no_rock_variance_pass) options.rock_variance_pass = false;
  options.rocks.model_min_height_m = options.matching.fault_detection.min_peak_to_plane_m;
  return options;
}

MissionRunOptions ParseMissionRunArguments(const std::vector<std::string>& arguments) {
  return ParsePlanArguments(arguments, &AddMissionRunOptions, "run").Resolve();
}

void AddRunCommand(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string mission;
    std::string out;
    MissionRunArguments mission_options;
    CLI::App* mission_group = nullptr;
    ExecutorArguments executor;
  };
  auto o = std::make_shared<Options>();
  auto* run = app.add_subcommand(
      "run",
      "The whole job on a mission folder: stereo, DTM and orthophoto per site, registration onto "
      "the orbital image, rock tie points with fault detection per leg, bundle adjustment, the "
      "anchored traverse and report.html. Finished sites and legs are reused on a re-run.");
  run->footer(kRunDetails);
  run->add_option("MISSION", o->mission, "Mission folder (or its mission.json)")->required();
  run->add_option("--out", o->out, "Output folder (created if needed)")->required();
  o->mission_group = run->add_option_group("Mission options");
  AddMissionRunOptions(o->mission_group, &o->mission_options);
  AddExecutorOptions(run, &o->executor);
  run->callback([o, &global] {
    const MissionRunOptions options = o->mission_options.Resolve();
    if (o->executor.plan_only || o->executor.executor != "local") {
      const WorkPlan plan = PlanMissionFolder(o->mission, o->out, options,
                                              ArgumentsGiven(*o->mission_group), global.overwrite);
      const bool finished = RunPlan(o->out, plan, o->executor, global);
      if (finished && !global.quiet) {
        PrintRunSummary(ReadRunSummary(o->out));
        std::printf("report: %s/report.html\n", o->out.c_str());
      }
      return;
    }
    const MissionRunSummary summary = RunMissionFolder(
        o->mission, o->out, options, global.overwrite, MakeProgressBar(global, "run"));
    if (!global.quiet) {
      PrintRunSummary(summary.record);
      std::printf("report: %s/report.html\n", o->out.c_str());
    }
  });

  auto report_dir = std::make_shared<std::string>();
  auto* report = app.add_subcommand("report", "Writes DIR/report.html from a finished run folder");
  report->footer(kReportDetails);
  report->add_option("DIR", *report_dir, "The --out folder of `areomap run`")->required();
  report->callback([report_dir, &global] {
    WriteRunReport(*report_dir);
    if (!global.quiet) std::printf("report: %s/report.html\n", report_dir->c_str());
  });
}

}  // namespace areomap::cli
