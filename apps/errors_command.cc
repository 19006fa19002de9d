// areomap errors simulate --out DIR: the localization error configuration study of ch. 4.1.2
// (Figs. 4.1-4.5) as a CSV table and one plot per traverse length.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <sstream>

#include "areomap/landmarks/localization_error.h"
#include "areomap/landmarks/localization_error_plot.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "commands.h"

namespace areomap::cli {

// What `areomap errors simulate --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kErrorsSimulateDetails =
    "The localization error study of ch. 4.1 (eqs. 4.1–4.9): relative error RE against "
    "convergence\n"
    "angle for 2–9 landmarks and traverse lengths 7.5–25 m with Navcam parameters (`--lengths`,\n"
    "`--landmarks`, `--sigma-p`, `--baseline`, `--focal-px`), as `study.csv`, `summary.json` and\n"
    "one plot per length (`re_<length>m.png`).";

namespace {

struct ErrorsSimulateOptions {
  std::string out;
  ConfigurationStudyOptions study;
};

void AddErrorsSimulateOptions(CLI::App* simulate, ErrorsSimulateOptions& o) {
  simulate->add_option("--out", o.out, "Output folder (created if needed)")->required();
  simulate->add_option("--lengths", o.study.traverse_lengths_m, "Traverse lengths [m]")
      ->check(NumberIn(0.0, 1000.0, Bound::kOpen))
      ->capture_default_str();
  simulate->add_option("--landmarks", o.study.landmark_counts, "Landmark counts (2 3 4 6 9)")
      ->check(IntegerAmong({2, 3, 4, 6, 9}))
      ->capture_default_str();
  // At least 0.01 degrees: at most 18 000 angles per curve.
  simulate->add_option("--step", o.study.convergence_step_deg, "Convergence angle step [deg]")
      ->check(NumberAtLeast(0.01))
      ->capture_default_str();
  simulate
      ->add_option("--sigma-p", o.study.camera.parallax_sigma_px,
                   "Parallax error sigma_p of eq. 4.3 [px]")
      ->check(NumberIn(0.0, 100.0, Bound::kOpen))
      ->capture_default_str();
  simulate->add_option("--baseline", o.study.camera.baseline_m, "Stereo base [m] (Navcam 0.2)")
      ->check(NumberIn(1e-3, 100.0))
      ->capture_default_str();
  simulate->add_option("--focal-px", o.study.camera.focal_px, "Focal length [px] (Navcam 1222.5)")
      ->check(NumberAbove(10.0))
      ->capture_default_str();
}

void CheckStudyIsFinite(const std::vector<ConfigurationSample>& samples) {
  for (const ConfigurationSample& sample : samples) {
    if (!std::isfinite(sample.relative_error_percent) || !std::isfinite(sample.position_sigma_m)) {
      throw Error(
          "errors simulate: the study gives a relative error that is not a finite number "
          "(--sigma-p, --baseline and --focal-px out of scale with each other?)");
    }
  }
}

std::string StudyCsv(const std::vector<ConfigurationSample>& samples) {
  std::ostringstream csv;
  csv << "landmarks,traverse_length_m,convergence_deg,figure_size_m,position_sigma_m,"
         "relative_error_percent\n";
  for (const ConfigurationSample& s : samples) {
    char line[160];
    std::snprintf(line, sizeof(line), "%d,%.3f,%.2f,%.4f,%.5f,%.4f\n", s.landmark_count,
                  s.traverse_length_m, s.convergence_deg, s.figure_size_m, s.position_sigma_m,
                  s.relative_error_percent);
    csv << line;
  }
  return csv.str();
}

// Smallest and largest relative error [%] per (traverse length [m], landmark count).
using RelativeErrorRanges = std::map<std::pair<double, int>, std::pair<double, double>>;

RelativeErrorRanges RelativeErrorExtremes(const std::vector<ConfigurationSample>& samples) {
  RelativeErrorRanges extremes;
  for (const ConfigurationSample& s : samples) {
    auto [it, inserted] = extremes.try_emplace({s.traverse_length_m, s.landmark_count},
                                               s.relative_error_percent, s.relative_error_percent);
    it->second.first = std::min(it->second.first, s.relative_error_percent);
    it->second.second = std::max(it->second.second, s.relative_error_percent);
  }
  return extremes;
}

// One re_<length>m.png per traverse length; returns their names.
nlohmann::json WriteStudyPlots(const OutputFolder& out,
                               const std::vector<ConfigurationSample>& samples,
                               const std::vector<double>& lengths) {
  nlohmann::json plots = nlohmann::json::array();
  for (double length : lengths) {
    char name[64];
    std::snprintf(name, sizeof(name), "re_%gm.png", length);
    WriteImage(out / name, RenderConfigurationPlot(samples, length));
    plots.push_back(name);
  }
  return plots;
}

nlohmann::json RangesJson(const RelativeErrorRanges& extremes) {
  nlohmann::json ranges = nlohmann::json::array();
  for (const auto& [key, range] : extremes) {
    ranges.push_back({{"traverse_length_m", key.first},
                      {"landmarks", key.second},
                      {"min_relative_error_percent", range.first},
                      {"max_relative_error_percent", range.second}});
  }
  return ranges;
}

void RunErrorsSimulate(const ErrorsSimulateOptions& o, const GlobalOptions& global) {
  // Staged: a study that fails (a plot of NaN) leaves the earlier study whole.
  OutputFolder out(o.out, OutputPolicy(global, "errors simulate", {"study.csv", "re_*m.png"}, {}));
  const std::vector<ConfigurationSample> samples = RunConfigurationStudy(o.study);
  CheckStudyIsFinite(samples);
  const RelativeErrorRanges extremes = RelativeErrorExtremes(samples);
  WriteFileAtomically(out / "study.csv", StudyCsv(samples));
  const nlohmann::json plots = WriteStudyPlots(out, samples, o.study.traverse_lengths_m);
  WriteSummary(out.dir(), {{"command", "errors simulate"},
                           {"samples", samples.size()},
                           {"table", "study.csv"},
                           {"plots", plots},
                           {"ranges", RangesJson(extremes)}});
  out.Commit();
  if (!global.quiet) {
    for (const auto& [key, range] : extremes) {
      std::printf("%5.1f m, %d landmarks: RE %.2f-%.2f %%\n", key.first, key.second, range.first,
                  range.second);
    }
  }
}

}  // namespace

void AddErrorsCommand(CLI::App& app, const GlobalOptions& global) {
  auto* errors = app.add_subcommand("errors", "Rover localization error analysis (ch. 4.1)");
  errors->require_subcommand(1);
  auto o = std::make_shared<ErrorsSimulateOptions>();
  auto* simulate = errors->add_subcommand(
      "simulate",
      "Relative localization error (eq. 4.9) against convergence angle for 2, 3, 4, 6, 9 "
      "landmarks and several traverse lengths (Figs. 4.2-4.5): study.csv, re_<length>m.png");
  simulate->footer(kErrorsSimulateDetails);
  AddErrorsSimulateOptions(simulate, *o);
  simulate->callback([o, &global] { RunErrorsSimulate(*o, global); });
}

}  // namespace areomap::cli
