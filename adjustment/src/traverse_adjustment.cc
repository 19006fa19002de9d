#include "areomap/adjustment/traverse_adjustment.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

std::string Format(const char* format, auto... values) {
  char text[512];
  std::snprintf(text, sizeof(text), format, values...);
  return text;
}

}  // namespace

void TraverseAdjustmentOptions::Check() const {
  bundle.Check();
  map.Check();
  RequireOption(std::isfinite(rock_tie_variance_factor) && rock_tie_variance_factor > 0.0,
                "TraverseAdjustmentOptions.rock_tie_variance_factor", "finite and > 0");
  if (!orbital_image.empty() && !std::filesystem::exists(orbital_image)) {
    throw Error(orbital_image.string() + ": no such file");
  }
}

std::string ReadableReport(const BundleResult& result, const AnchoredTraverse& traverse) {
  std::string text = result.BriefReport() + "\n\n";
  const bool truth = !traverse.sites.empty() && std::isfinite(traverse.sites[0].adjusted_error_m);
  text += "site   north_m    east_m   down_m  sigma_n  sigma_e  sigma_d  shift_m  links";
  text += truth ? "  error_m (telemetry -> adjusted)\n" : "\n";
  for (size_t k = 0; k < traverse.sites.size(); ++k) {
    const AnchoredSite& s = traverse.sites[k];
    const SiteReport& r = result.sites[k];
    const Eigen::Vector3d& p = s.position_in_traverse;
    text += Format(
        "%4d %9.3f %9.3f %8.3f %8.3f %8.3f %8.3f %8.3f  %dt %dc %dh%s%s", s.site, p.x(), p.y(),
        p.z(), std::sqrt(s.covariance_in_traverse(0, 0)), std::sqrt(s.covariance_in_traverse(1, 1)),
        s.sigma_down_m, (s.position_in_traverse - s.initial_in_traverse).norm(), r.tie_points,
        r.control_points, r.heights, r.held ? " held" : "", s.only_priors ? " PRIORS ONLY" : "");
    if (truth) text += Format("  %.3f -> %.3f", s.initial_error_m, s.adjusted_error_m);
    text += "\n";
  }
  text += "\nrejected observations:\n";
  int rejected = 0;
  for (const ObservationReport& o : result.observations) {
    if (!o.rejected) continue;
    ++rejected;
    text += "  " + ToString(o.kind) + " " + o.id + ": " + o.reason + "\n";
  }
  if (rejected == 0) text += "  none\n";
  if (!result.images.empty()) {
    text += "\nimage residuals (rms px, observations):\n";
    for (const ImageReport& image : result.images) {
      text += Format("  %-32s %6.3f %4d\n", image.image.c_str(), image.rms_px, image.observations);
    }
  }
  text += "\nleg        length_m  predicted_RE_%";
  text += truth ? "  telemetry_RE_%  adjusted_RE_%\n" : "\n";
  for (const LegError& leg : traverse.legs) {
    text += Format("%3d -> %3d %9.2f %15.3f", leg.site_a, leg.site_b, leg.length_m,
                   100.0 * leg.predicted_re);
    if (truth) text += Format(" %15.2f %14.3f", 100.0 * leg.initial_re, 100.0 * leg.adjusted_re);
    text += "\n";
  }
  if (truth) {
    text += Format(
        "\nlength %.1f m; end-point error telemetry %.2f m (%.2f %%), adjusted %.2f m (%.3f %%); "
        "median adjusted leg RE %.3f %%\n",
        traverse.length_m, traverse.initial_end_error_m,
        100.0 * traverse.initial_end_error_m / traverse.length_m, traverse.adjusted_end_error_m,
        100.0 * traverse.adjusted_end_error_m / traverse.length_m,
        100.0 * traverse.median_adjusted_re);
  }
  return text;
}

nlohmann::json AdjustTraverse(const std::vector<std::filesystem::path>& inputs,
                              const std::filesystem::path& out_dir,
                              const TraverseAdjustmentOptions& options,
                              const ProgressCallback& progress) {
  options.Check();
  return AdjustTraverseInput(ReadBundleInput(inputs), out_dir, options, progress);
}

nlohmann::json AdjustTraverseInput(BundleInputFile file, const std::filesystem::path& out_dir,
                                   const TraverseAdjustmentOptions& options,
                                   const ProgressCallback& progress) {
  options.Check();
  for (TiePoint& t : file.input.tie_points) {
    if (t.source != "rock") continue;
    t.covariance_in_a *= options.rock_tie_variance_factor;
    t.covariance_in_b *= options.rock_tie_variance_factor;
  }
  const BundleResult result = AdjustBundle(file.input, options.bundle, progress);
  const AnchoredTraverse traverse = AnchorTraverse(file.input, result, file.truth);
  // The map first: it is the one output that reads another input (the orbital image), so an
  // unusable image fails the command before any earlier result in `out_dir` is replaced.
  if (!options.orbital_image.empty()) {
    WriteTraverseMap(out_dir / "traverse_map.png", traverse, options.orbital_image, options.map);
  }
  WriteFileAtomically(out_dir / "adjustment.json", ToJson(result).dump(1) + "\n");
  WriteFileAtomically(out_dir / "report.txt", ReadableReport(result, traverse));
  WriteTraverseSitesCsv(out_dir / "sites.csv", traverse);
  WriteLegTableCsv(out_dir / "legs.csv", traverse);
  WriteTraverseGeoPackage(out_dir / "traverse.gpkg", traverse, file.input.body);
  nlohmann::json files = {"adjustment.json", "report.txt", "sites.csv", "legs.csv",
                          "traverse.gpkg"};
  if (!options.orbital_image.empty()) files.push_back("traverse_map.png");
  int only_priors = 0;
  double worst_sigma = 0.0;
  for (const AnchoredSite& s : traverse.sites) {
    only_priors += s.only_priors ? 1 : 0;
    worst_sigma = std::max(worst_sigma, s.ellipse.semi_major_m);
  }
  nlohmann::json summary = {{"sites", file.input.site_count},
                            {"tie_points", file.input.tie_points.size()},
                            {"rock_tie_variance_factor", options.rock_tie_variance_factor},
                            {"control_points", file.input.control_points.size()},
                            {"priors", file.input.priors.size()},
                            {"heights", file.input.heights.size()},
                            {"rejected", result.rejected},
                            {"sites_with_priors_only", only_priors},
                            {"sigma0", result.sigma0},
                            {"redundancy", result.redundancy},
                            {"converged", result.converged},
                            {"length_m", traverse.length_m},
                            {"largest_horizontal_sigma_m", worst_sigma},
                            {"solve_seconds", result.solve_seconds},
                            {"covariance_seconds", result.covariance_seconds},
                            {"files", files}};
  if (!file.truth.empty()) {
    summary["initial_end_error_m"] = traverse.initial_end_error_m;
    summary["adjusted_end_error_m"] = traverse.adjusted_end_error_m;
    summary["median_adjusted_leg_re"] = traverse.median_adjusted_re;
    // Horizontal errors against the truth, and how many lie inside the reported 1 sigma (the
    // semi-major axis of the site's error ellipse).
    std::vector<double> errors;
    int within = 0;
    for (const AnchoredSite& s : traverse.sites) {
      errors.push_back(s.adjusted_error_m);
      within += s.adjusted_error_m <= s.ellipse.semi_major_m ? 1 : 0;
    }
    std::sort(errors.begin(), errors.end());
    if (!errors.empty()) {
      const size_t half = errors.size() / 2;
      summary["median_adjusted_error_m"] =
          errors.size() % 2 == 1 ? errors[half] : 0.5 * (errors[half - 1] + errors[half]);
      summary["worst_adjusted_error_m"] = errors.back();
      summary["sites_within_1sigma"] = within;
    }
  }
  return summary;
}

}  // namespace areomap
