#include "areomap/pipeline/run_report.h"

#include <cpl_string.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "areomap/map/atomic_file.h"
#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "areomap/pipeline/run_summary.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '&':
        out += "&amp;";
        break;
      case '"':
        out += "&quot;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// An <img> with the PNG embedded (GDAL's base64), or a note when the file is absent.
std::string EmbeddedPng(const fs::path& path, const std::string& alt, int max_width_px) {
  if (!fs::is_regular_file(path)) return "<p><em>" + Escape(alt) + ": not produced</em></p>";
  const std::string bytes = ReadText(path);
  char* encoded =
      CPLBase64Encode(static_cast<int>(bytes.size()), reinterpret_cast<const GByte*>(bytes.data()));
  std::string html = "<img alt=\"" + Escape(alt) +
                     "\" style=\"max-width:" + std::to_string(max_width_px) +
                     "px;width:100%\" src=\"data:image/png;base64," + encoded + "\">";
  CPLFree(encoded);
  return html;
}

// A CSV file (header row, plain comma-separated fields) as an HTML table.
std::string CsvTable(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return "<p><em>" + Escape(path.filename().string()) + ": not produced</em></p>";
  std::string html = "<table>";
  std::string line;
  for (bool header = true; std::getline(in, line); header = false) {
    html += "<tr>";
    for (const std::string& field : SplitCsvLine(line)) {
      html += (header ? "<th>" : "<td>") + Escape(field) + (header ? "</th>" : "</td>");
    }
    html += "</tr>";
  }
  return html + "</table>";
}

// The figure in `format`; a dash when missing or recorded as null (NaN).
std::string Number(const OptionalNumber& value, const char* format) {
  if (!mission_run::Known(value)) return "&ndash;";
  char text[64];
  std::snprintf(text, sizeof(text), format, *value);
  return text;
}

std::string Scaled(const OptionalNumber& value, double factor) {
  return Number(value ? OptionalNumber(factor * *value) : std::nullopt, "%.2f %%");
}

std::string GuidedRegistrationFigure(const mission_run::GuidedPassesResult& guided) {
  std::string text = std::to_string(guided.registered_first_pass.size()) + " around telemetry";
  for (const mission_run::GuidedPassRecord& pass : guided.passes) {
    text += " + " + std::to_string(pass.registered.size()) + " guided (pass " +
            std::to_string(pass.pass) + "; " + std::to_string(pass.replaced.size()) +
            " re-matched)";
  }
  return text;
}

std::string CratersFigure(const mission_run::CratersUnitResult& craters) {
  std::string text = Number(craters.craters, "%.0f");
  if (craters.score) {
    text += " (truth " + Number(craters.score->truth, "%.0f") + ": precision " +
            Number(craters.score->precision, "%.2f") + ", recall " +
            Number(craters.score->recall, "%.2f") + ")";
  }
  return text;
}

std::string KeyFigures(const RunSummary& summary) {
  const mission_run::AdjustmentResult adjustment =
      summary.adjustment.value_or(mission_run::AdjustmentResult{});
  std::string html = "<table class=\"figures\">";
  const auto row = [&](const std::string& name, const std::string& value) {
    html += "<tr><th>" + name + "</th><td>" + value + "</td></tr>";
  };
  row("mission", Escape(summary.name));
  row("sites", std::to_string(summary.sites.size()));
  row("traverse length", Number(adjustment.length_m, "%.1f m"));
  row("tie points / control points",
      Number(adjustment.tie_points, "%.0f") + " / " + Number(adjustment.control_points, "%.0f"));
  row("observations rejected", Number(adjustment.rejected, "%.0f"));
  row("sigma0", Number(adjustment.sigma0, "%.3f"));
  const mission_run::TieVarianceRecord ties =
      summary.tie_variance.value_or(mission_run::TieVarianceRecord{});
  row("rock tie fits: pooled sigma0&sup2; (95 % upper bound; legs, redundancy)",
      Number(ties.sigma0_squared, "%.3f") + " (" + Number(ties.sigma0_squared_upper_95, "%.3f") +
          "; " + Number(ties.legs, "%.0f") + ", " + Number(ties.redundancy, "%.0f") + ")");
  row("rock tie variance factor applied by the legs' second pass",
      mission_run::Known(ties.applied_factor)
          ? Number(ties.applied_factor, "%.3f")
          : std::string("none (too little redundancy, or off)"));
  row("end-point error, telemetry (truth)", Number(adjustment.initial_end_error_m, "%.3f m"));
  row("end-point error, adjusted (truth)", Number(adjustment.adjusted_end_error_m, "%.3f m"));
  row("median adjusted leg RE (truth)", Scaled(adjustment.median_adjusted_leg_re, 100.0));
  row("largest 1&sigma; ellipse", Number(adjustment.largest_horizontal_sigma_m, "%.3f m"));
  if (mission_run::Known(adjustment.median_adjusted_error_m)) {
    row("adjusted horizontal error, median / worst (truth)",
        Number(adjustment.median_adjusted_error_m, "%.3f m") + " / " +
            Number(adjustment.worst_adjusted_error_m, "%.3f m"));
    row("sites within their 1&sigma; ellipse's semi-major axis (truth)",
        Number(adjustment.sites_within_1sigma, "%.0f"));
  }
  if (summary.guided) {
    row("sites registered on the orbital image", GuidedRegistrationFigure(*summary.guided));
  }
  if (summary.products && summary.products->dtm_minus_orbital_adjusted) {
    const auto rms = [](const std::optional<mission_run::TraverseDifference>& d) {
      return Number(d ? d->rms_m : std::nullopt, "%.3f m");
    };
    row("traverse DTM &minus; orbital DTM, RMS: telemetry / adjusted poses",
        rms(summary.products->dtm_minus_orbital_telemetry) + " / " +
            rms(summary.products->dtm_minus_orbital_adjusted));
  }
  if (summary.craters && !summary.craters->skipped) {
    row("craters on the orbital image", CratersFigure(*summary.craters));
  }
  row("run time", Number(summary.seconds, "%.0f s"));
  return html + "</table>";
}

// Wall time per stage: of the invocation that wrote the summary, and as recorded by the units
// when they were computed (a resumed run reuses most of them).
std::string StageTimes(const RunSummary& summary) {
  if (summary.stage_seconds.empty()) return "";
  const auto seconds = [](const std::map<std::string, double>& times, const char* stage) {
    const auto it = times.find(stage);
    return it == times.end() ? OptionalNumber() : OptionalNumber(it->second);
  };
  std::string html =
      "<h2>Run time per stage</h2><p>Wall time of the run that wrote this folder, and what each "
      "stage cost when its units were computed (this run or an earlier one; per-site stages and "
      "legs summed over the units, the sites ran in parallel).</p><table><tr><th>stage</th>"
      "<th>this run [s]</th><th>when computed [s]</th></tr>";
  const auto row = [&](const std::string& name, const OptionalNumber& now,
                       const OptionalNumber& then) {
    html += "<tr><th>" + name + "</th><td>" + Number(now, "%.1f") + "</td><td>" +
            Number(then, "%.1f") + "</td></tr>";
  };
  row("sites", seconds(summary.stage_seconds, "sites"), std::nullopt);
  for (const char* stage : {"stereo", "dtm", "ortho", "registration"}) {
    row(std::string("&nbsp;&nbsp;") + stage, std::nullopt,
        seconds(summary.computed_seconds, stage));
  }
  for (const char* stage : {"legs", "craters", "adjustment", "products"}) {
    row(stage, seconds(summary.stage_seconds, stage), seconds(summary.computed_seconds, stage));
  }
  return html + "</table>";
}

std::string DifferenceRow(const std::string& name,
                          const std::optional<mission_run::TraverseDifference>& d) {
  const mission_run::TraverseDifference stats = d.value_or(mission_run::TraverseDifference{});
  return "<tr><th>" + name + "</th><td>" +
         Number(d ? OptionalNumber(stats.cells) : std::nullopt, "%.0f") + "</td><td>" +
         Number(stats.mean_m, "%.3f") + "</td><td>" + Number(stats.stddev_m, "%.3f") + "</td><td>" +
         Number(stats.rms_m, "%.3f") + "</td><td>" + Number(stats.median_abs_m, "%.3f") +
         "</td></tr>";
}

// The whole-traverse DTM and orthomosaic, and how they sit on the orbital data.
std::string ProductsSection(const fs::path& run_dir, const RunSummary& summary) {
  if (!summary.products || *summary.products == mission_run::ProductsUnitResult{}) return "";
  const mission_run::ProductsUnitResult& products = *summary.products;
  std::string html =
      "<h2>Traverse DTM and orthomosaic (adjusted poses)</h2><p>Every site's stereo points "
      "gridded at " +
      Number(products.posting_m, "%.2f m") +
      " with the bundle-adjusted site poses (<code>products/traverse_dtm.tif</code>, " +
      Number(products.dtm_known_area_m2, "%.0f") +
      " m&sup2;) and every site's images draped on it "
      "(<code>products/traverse_ortho.tif</code>, " +
      Number(products.ortho_valid_area_m2, "%.0f") + " m&sup2;).</p>" +
      EmbeddedPng(run_dir / "products" / "traverse_ortho.png", "traverse orthomosaic", 1000) +
      EmbeddedPng(run_dir / "products" / "traverse_dtm.png", "traverse DTM (shaded relief)", 1000);
  if (products.dtm_minus_orbital_adjusted) {
    html +=
        "<h3>Rover DTM &minus; orbital DTM</h3><p>Over the cells both know; a misplaced site "
        "shows as a height difference where the ground slopes.</p><table><tr><th>site "
        "poses</th><th>cells</th><th>mean [m]</th><th>std [m]</th><th>RMS [m]</th><th>median "
        "|d| [m]</th></tr>" +
        DifferenceRow("telemetry", products.dtm_minus_orbital_telemetry) +
        DifferenceRow("adjusted", products.dtm_minus_orbital_adjusted) + "</table>";
  }
  if (products.ortho_vs_orbital_adjusted) {
    const auto correlation = [](const std::optional<mission_run::TraverseCorrelation>& c) {
      return Number(c ? c->correlation : std::nullopt, "%.3f");
    };
    html += "<p>Orthomosaic vs orbital image, correlation over the cells both cover: " +
            correlation(products.ortho_vs_orbital_telemetry) + " with the telemetry poses, " +
            correlation(products.ortho_vs_orbital_adjusted) + " with the adjusted poses.</p>";
  }
  return html;
}

std::string CratersSection(const fs::path& run_dir, const RunSummary& summary) {
  if (!fs::exists(run_dir / "craters")) return "";
  std::string html = "<h2>Craters on the orbital image</h2>";
  if (summary.craters && !summary.craters->skipped) {
    const mission_run::CratersUnitResult& craters = *summary.craters;
    html += "<p>" + Number(craters.craters, "%.0f") + " rims from " +
            Number(craters.min_diameter_m, "%.1f m") +
            " across (<code>craters/craters.csv</code>, <code>craters.gpkg</code>).";
    if (craters.score) {
      const mission_run::CraterScoreRecord& s = *craters.score;
      html += " Against the truth catalogue (" + Escape(s.rule) +
              "): " + Number(s.matched_truth, "%.0f") + " of " + Number(s.truth, "%.0f") +
              " true craters found, precision " + Number(s.precision, "%.2f") + ", recall " +
              Number(s.recall, "%.2f") + ", median centre error " +
              Number(s.median_center_error_px, "%.2f px") + ".";
    }
    html += "</p>";
  }
  return html + EmbeddedPng(run_dir / "craters" / "overlay.png", "crater overlay", 1000);
}

// The guided re-registration of a site (summary.json "guided_registration"), as a paragraph;
// empty when the site was not re-registered.
std::string GuidedSiteParagraph(const fs::path& run_dir,
                                const std::optional<mission_run::GuidedPassesResult>& guided,
                                int number) {
  if (!guided) return "";
  for (const mission_run::GuidedPassRecord& pass : guided->passes) {
    for (const mission_run::GuidedAttemptRecord& a : pass.attempted) {
      if (a.site != number) continue;
      char folder[64];
      std::snprintf(folder, sizeof(folder), "pass_%d/site_%03d", pass.pass, number);
      std::string html = "<p>Guided registration, pass " + std::to_string(pass.pass) +
                         " (around the adjusted position, turned " +
                         Number(a.prior.rotation_deg, "%.1f") + "&deg;, window " +
                         Number(a.search_radius_px, "&plusmn;%.0f px") + " = 3 &times; " +
                         Number(a.prior.sigma_m, "%.2f m") + "): ";
      if (a.matched) {
        html += "<b>matched</b>, CC " + Number(a.correlation, "%.3f") + " (best at wrong offsets " +
                Number(a.null_highest_correlation, "%.3f") + "), " +
                Number(a.control_points, "%.0f") + " control points.";
      } else {
        html += "<b>no match</b> (" + Escape(a.reason) + ").";
      }
      return html + "</p>" +
             EmbeddedPng(run_dir / "guided" / folder / "correlation_surface.png",
                         "guided correlation surface", 160);
    }
  }
  return "";
}

std::string SiteSection(const fs::path& run_dir, const mission_run::SiteUnitResult& site) {
  char folder[32];
  std::snprintf(folder, sizeof(folder), "site_%03d", site.site);
  const mission_run::SiteRegistrationResult& r = site.registration;
  std::string html = "<h3>Site " + std::to_string(site.site) + "</h3><p>" +
                     Number(site.points, "%.0f") + " stereo points; DTM " +
                     Number(site.dtm_known_area_m2, "%.0f") + " m&sup2;; orthophoto " +
                     Number(site.ortho_valid_area_m2, "%.0f") + " m&sup2;. ";
  if (r.matched) {
    html += "Registration: <b>matched</b>, CC " + Number(r.correlation, "%.3f") + ", peak ratio " +
            Number(r.peak_ratio, "%.2f") + ", " + Number(r.control_points, "%.0f") +
            " control points.";
  } else {
    html += "Registration: <b>no match</b> (" + Escape(r.reason) + ").";
  }
  html += "</p><details><summary>registration details and correlation surface</summary><pre>" +
          Escape(r.ToJson().dump(2)) + "</pre>" +
          EmbeddedPng(run_dir / "sites" / folder / "correlation_surface.png", "correlation surface",
                      320) +
          "</details>";
  return html;
}

std::string LegSection(const mission_run::LegUnitResult& leg) {
  std::string html = "<h3>Leg " + std::to_string(leg.site_a) + " &rarr; " +
                     std::to_string(leg.site_b) + "</h3><p>Outcome: <b>" +
                     Escape(leg.match.outcome) + "</b>, " + Number(leg.match.tie_points, "%.0f") +
                     " tie points, RE " + Number(leg.match.relative_error_percent, "%.2f %%") +
                     ", telemetry distance " + Number(leg.telemetry_distance_m, "%.1f m") + ".";
  if (leg.first_pass) {
    html += " First pass (a-priori tie covariances): " + Escape(leg.first_pass->outcome) + ", " +
            Number(leg.first_pass->tie_points, "%.0f") + " tie points, RE " +
            Number(leg.first_pass->relative_error_percent, "%.2f %%") +
            "; this pass scaled them by " + Number(leg.match.tie_variance_factor, "%.3f") + ".";
  }
  html += "</p>";
  html +=
      "<table><tr><th>module</th><th>rule</th><th>value</th><th>threshold</th>"
      "<th>verdict</th></tr>";
  for (const FaultCheck& c : leg.faults.checks) {
    const std::string verdict = Escape(ToString(c.verdict));
    html += "<tr class=\"" + verdict + "\"><td>" + Escape(c.module) + "</td><td>" + Escape(c.rule) +
            "</td><td>" + Number(c.value, "%.3g") + " " + Escape(c.unit) + "</td><td>" +
            Number(c.threshold, "%.3g") + "</td><td>" + verdict + "</td></tr>";
  }
  return html + "</table>";
}

// The paragraph over the sites' registrations: how many registered around telemetry and in each
// guided pass.
std::string RegistrationOverview(const RunSummary& summary) {
  if (!summary.guided) return "";
  const mission_run::GuidedPassesResult& guided = *summary.guided;
  std::string html = "<p>" + std::to_string(guided.registered_first_pass.size()) + " of " +
                     std::to_string(summary.sites.size()) +
                     " sites registered around their telemetry positions";
  for (const mission_run::GuidedPassRecord& pass : guided.passes) {
    html += "; guided pass " + std::to_string(pass.pass) + " (around the adjusted " + "poses, " +
            std::to_string(pass.attempted.size()) +
            " sites tried): " + std::to_string(pass.registered.size()) + " more";
    if (const size_t replaced = pass.replaced.size(); replaced > 0) {
      html += " and " + std::to_string(replaced) +
              " re-matched whose first turn was at the edge of the rotation search";
    }
  }
  return html + ".</p>";
}

void WriteRunReportHtml(const fs::path& run_dir, const RunSummary& summary) {
  std::string html =
      "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>areomap run: " +
      Escape(summary.name) +
      "</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}"
      "table{border-collapse:collapse;margin:.5em 0;font-size:90%}td,th{border:1px solid #bbb;"
      "padding:2px 6px;text-align:right}th{background:#eee}tr.fail td{background:#fdd}"
      "table.figures th{text-align:left}pre{font-size:80%;background:#f6f6f6}</style></head><body>"
      "<h1>areomap run: " +
      Escape(summary.name) + "</h1>";
  html += "<h2>Key figures</h2>" + KeyFigures(summary);
  html +=
      "<h2>Traverse</h2><p>Telemetry (red), adjusted with 1&sigma; ellipses (green, "
      "enlarged) and, when known, true (blue) positions over the orbital image.</p>" +
      EmbeddedPng(run_dir / "adjustment" / "traverse_map.png", "traverse map", 1000);
  html += "<h3>Anchored sites</h3>" + CsvTable(run_dir / "adjustment" / "sites.csv");
  html += "<h3>Legs (relative error, Tables 4.6 / 5.2)</h3>" +
          CsvTable(run_dir / "adjustment" / "legs.csv");
  html += "<h2>Orbital registration per site</h2>" + RegistrationOverview(summary);
  for (const mission_run::SiteUnitResult& site : summary.sites) {
    html += SiteSection(run_dir, site) + GuidedSiteParagraph(run_dir, summary.guided, site.site);
  }
  html += "<h2>Tie points and fault detection per leg</h2>";
  for (const mission_run::LegUnitResult& leg : summary.legs) html += LegSection(leg);
  html += ProductsSection(run_dir, summary);
  html += CratersSection(run_dir, summary);
  html += StageTimes(summary);
  html += "</body></html>\n";
  WriteFileAtomically(run_dir / "report.html", html);
}

}  // namespace

void WriteRunReport(const fs::path& run_dir) {
  WriteRunReportHtml(run_dir, ReadRunSummary(run_dir));
}

}  // namespace areomap
