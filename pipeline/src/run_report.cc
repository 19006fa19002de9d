#include "areomap/pipeline/run_report.h"

#include <cpl_string.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/csv.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

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

std::string Number(const json& value, const char* format) {
  if (!value.is_number()) return "&ndash;";
  char text[64];
  std::snprintf(text, sizeof(text), format, value.get<double>());
  return text;
}

std::string KeyFigures(const json& summary) {
  const json& adjustment = summary.value("adjustment", json::object());
  std::string html = "<table class=\"figures\">";
  const auto row = [&](const std::string& name, const std::string& value) {
    html += "<tr><th>" + name + "</th><td>" + value + "</td></tr>";
  };
  row("mission", Escape(summary.value("name", std::string())));
  row("sites", std::to_string(summary.value("sites", json::array()).size()));
  row("traverse length", Number(adjustment.value("length_m", json()), "%.1f m"));
  row("tie points / control points",
      Number(adjustment.value("tie_points", json()), "%.0f") + " / " +
          Number(adjustment.value("control_points", json()), "%.0f"));
  row("observations rejected", Number(adjustment.value("rejected", json()), "%.0f"));
  row("sigma0", Number(adjustment.value("sigma0", json()), "%.3f"));
  const json& ties = summary.value("rock_tie_variance", json::object());
  row("rock tie fits: pooled sigma0&sup2; (95 % upper bound; legs, redundancy)",
      Number(ties.value("sigma0_squared", json()), "%.3f") + " (" +
          Number(ties.value("sigma0_squared_upper_95", json()), "%.3f") + "; " +
          Number(ties.value("legs", json()), "%.0f") + ", " +
          Number(ties.value("redundancy", json()), "%.0f") + ")");
  row("rock tie variance factor applied by the legs' second pass",
      ties.value("applied_factor", json()).is_number()
          ? Number(ties["applied_factor"], "%.3f")
          : std::string("none (too little redundancy, or off)"));
  row("end-point error, telemetry (truth)",
      Number(adjustment.value("initial_end_error_m", json()), "%.3f m"));
  row("end-point error, adjusted (truth)",
      Number(adjustment.value("adjusted_end_error_m", json()), "%.3f m"));
  row("median adjusted leg RE (truth)",
      Number(adjustment.value("median_adjusted_leg_re", json()).is_number()
                 ? json(100.0 * adjustment["median_adjusted_leg_re"].get<double>())
                 : json(),
             "%.2f %%"));
  row("largest 1&sigma; ellipse",
      Number(adjustment.value("largest_horizontal_sigma_m", json()), "%.3f m"));
  if (adjustment.contains("median_adjusted_error_m")) {
    row("adjusted horizontal error, median / worst (truth)",
        Number(adjustment["median_adjusted_error_m"], "%.3f m") + " / " +
            Number(adjustment.value("worst_adjusted_error_m", json()), "%.3f m"));
    row("sites within their 1&sigma; ellipse's semi-major axis (truth)",
        Number(adjustment.value("sites_within_1sigma", json()), "%.0f"));
  }
  const json& guided = summary.value("guided_registration", json::object());
  if (guided.contains("registered_first_pass")) {
    std::string text = std::to_string(guided["registered_first_pass"].size()) + " around telemetry";
    for (const json& pass : guided.value("passes", json::array())) {
      text += " + " + std::to_string(pass.value("registered", json::array()).size()) +
              " guided (pass " + std::to_string(pass.value("pass", 0)) + "; " +
              std::to_string(pass.value("replaced", json::array()).size()) + " re-matched)";
    }
    row("sites registered on the orbital image", text);
  }
  const json& products = summary.value("products", json::object());
  if (products.is_object() && products.contains("dtm_minus_orbital_adjusted")) {
    const auto rms = [&](const char* key) {
      return Number(products[key].value("rms_m", json()), "%.3f m");
    };
    row("traverse DTM &minus; orbital DTM, RMS: telemetry / adjusted poses",
        rms("dtm_minus_orbital_telemetry") + " / " + rms("dtm_minus_orbital_adjusted"));
  }
  const json& craters = summary.value("craters", json::object());
  if (craters.is_object() && craters.contains("craters")) {
    std::string text = Number(craters["craters"], "%.0f");
    if (craters.contains("score")) {
      const json& score = craters["score"];
      text += " (truth " + Number(score.value("truth", json()), "%.0f") + ": precision " +
              Number(score.value("precision", json()), "%.2f") + ", recall " +
              Number(score.value("recall", json()), "%.2f") + ")";
    }
    row("craters on the orbital image", text);
  }
  row("run time", Number(summary.value("seconds", json()), "%.0f s"));
  return html + "</table>";
}

// Wall time per stage: of the invocation that wrote the summary, and as recorded by the units
// when they were computed (a resumed run reuses most of them).
std::string StageTimes(const json& summary) {
  const json stages = summary.value("stage_seconds", json::object());
  const json computed = summary.value("computed_seconds", json::object());
  if (!stages.is_object() || stages.empty()) return "";
  std::string html =
      "<h2>Run time per stage</h2><p>Wall time of the run that wrote this folder, and what each "
      "stage cost when its units were computed (this run or an earlier one; per-site stages and "
      "legs summed over the units, the sites ran in parallel).</p><table><tr><th>stage</th>"
      "<th>this run [s]</th><th>when computed [s]</th></tr>";
  const auto row = [&](const std::string& name, const json& now, const json& then) {
    html += "<tr><th>" + name + "</th><td>" + Number(now, "%.1f") + "</td><td>" +
            Number(then, "%.1f") + "</td></tr>";
  };
  row("sites", stages.value("sites", json()), json());
  for (const char* stage : {"stereo", "dtm", "ortho", "registration"}) {
    row(std::string("&nbsp;&nbsp;") + stage, json(), computed.value(stage, json()));
  }
  for (const char* stage : {"legs", "craters", "adjustment", "products"}) {
    row(stage, stages.value(stage, json()), computed.value(stage, json()));
  }
  return html + "</table>";
}

std::string DifferenceRow(const std::string& name, const json& stats) {
  return "<tr><th>" + name + "</th><td>" + Number(stats.value("cells", json()), "%.0f") +
         "</td><td>" + Number(stats.value("mean_m", json()), "%.3f") + "</td><td>" +
         Number(stats.value("stddev_m", json()), "%.3f") + "</td><td>" +
         Number(stats.value("rms_m", json()), "%.3f") + "</td><td>" +
         Number(stats.value("median_abs_m", json()), "%.3f") + "</td></tr>";
}

// The whole-traverse DTM and orthomosaic, and how they sit on the orbital data.
std::string ProductsSection(const fs::path& run_dir, const json& summary) {
  const json& products = summary.value("products", json::object());
  if (!products.is_object() || products.empty()) return "";
  std::string html =
      "<h2>Traverse DTM and orthomosaic (adjusted poses)</h2><p>Every site's stereo points "
      "gridded at " +
      Number(products.value("posting_m", json()), "%.2f m") +
      " with the bundle-adjusted site poses (<code>products/traverse_dtm.tif</code>, " +
      Number(products.value("dtm_known_area_m2", json()), "%.0f") +
      " m&sup2;) and every site's images draped on it "
      "(<code>products/traverse_ortho.tif</code>, " +
      Number(products.value("ortho_valid_area_m2", json()), "%.0f") + " m&sup2;).</p>" +
      EmbeddedPng(run_dir / "products" / "traverse_ortho.png", "traverse orthomosaic", 1000) +
      EmbeddedPng(run_dir / "products" / "traverse_dtm.png", "traverse DTM (shaded relief)", 1000);
  if (products.contains("dtm_minus_orbital_adjusted")) {
    html +=
        "<h3>Rover DTM &minus; orbital DTM</h3><p>Over the cells both know; a misplaced site "
        "shows as a height difference where the ground slopes.</p><table><tr><th>site "
        "poses</th><th>cells</th><th>mean [m]</th><th>std [m]</th><th>RMS [m]</th><th>median "
        "|d| [m]</th></tr>" +
        DifferenceRow("telemetry", products["dtm_minus_orbital_telemetry"]) +
        DifferenceRow("adjusted", products["dtm_minus_orbital_adjusted"]) + "</table>";
  }
  if (products.contains("ortho_vs_orbital_adjusted")) {
    const auto correlation = [&](const char* key) {
      return Number(products[key].value("correlation", json()), "%.3f");
    };
    html += "<p>Orthomosaic vs orbital image, correlation over the cells both cover: " +
            correlation("ortho_vs_orbital_telemetry") + " with the telemetry poses, " +
            correlation("ortho_vs_orbital_adjusted") + " with the adjusted poses.</p>";
  }
  return html;
}

std::string CratersSection(const fs::path& run_dir, const json& summary) {
  if (!fs::exists(run_dir / "craters")) return "";
  const json& craters = summary.value("craters", json::object());
  std::string html = "<h2>Craters on the orbital image</h2>";
  if (craters.is_object() && craters.contains("craters")) {
    html += "<p>" + Number(craters["craters"], "%.0f") + " rims from " +
            Number(craters.value("min_diameter_m", json()), "%.1f m") +
            " across (<code>craters/craters.csv</code>, <code>craters.gpkg</code>).";
    if (craters.contains("score")) {
      const json& s = craters["score"];
      html += " Against the truth catalogue (" + Escape(s.value("rule", std::string())) +
              "): " + Number(s.value("matched_truth", json()), "%.0f") + " of " +
              Number(s.value("truth", json()), "%.0f") + " true craters found, precision " +
              Number(s.value("precision", json()), "%.2f") + ", recall " +
              Number(s.value("recall", json()), "%.2f") + ", median centre error " +
              Number(s.value("median_center_error_px", json()), "%.2f px") + ".";
    }
    html += "</p>";
  }
  return html + EmbeddedPng(run_dir / "craters" / "overlay.png", "crater overlay", 1000);
}

// The guided re-registration of a site (summary.json "guided_registration"), as a paragraph;
// empty when the site was not re-registered.
std::string GuidedSiteParagraph(const fs::path& run_dir, const json& guided, int number) {
  for (const json& pass : guided.value("passes", json::array())) {
    for (const json& a : pass.value("attempted", json::array())) {
      if (a.value("site", -1) != number) continue;
      const json& prior = a.value("prior", json::object());
      const int p = pass.value("pass", 0);
      char folder[64];
      std::snprintf(folder, sizeof(folder), "pass_%d/site_%03d", p, number);
      std::string html = "<p>Guided registration, pass " + std::to_string(p) +
                         " (around the adjusted position, turned " +
                         Number(prior.value("rotation_deg", json()), "%.1f") + "&deg;, window " +
                         Number(a.value("search_radius_px", json()), "&plusmn;%.0f px") +
                         " = 3 &times; " + Number(prior.value("sigma_m", json()), "%.2f m") + "): ";
      if (a.value("matched", false)) {
        html += "<b>matched</b>, CC " + Number(a.value("correlation", json()), "%.3f") +
                " (best at wrong offsets " +
                Number(a.value("null_highest_correlation", json()), "%.3f") + "), " +
                Number(a.value("control_points", json()), "%.0f") + " control points.";
      } else {
        html += "<b>no match</b> (" + Escape(a.value("reason", std::string("?"))) + ").";
      }
      return html + "</p>" +
             EmbeddedPng(run_dir / "guided" / folder / "correlation_surface.png",
                         "guided correlation surface", 160);
    }
  }
  return "";
}

std::string SiteSection(const fs::path& run_dir, const json& site) {
  const int number = site.value("site", -1);
  char folder[32];
  std::snprintf(folder, sizeof(folder), "site_%03d", number);
  const json& r = site.value("registration", json::object());
  std::string html = "<h3>Site " + std::to_string(number) + "</h3><p>" +
                     Number(site.value("points", json()), "%.0f") + " stereo points; DTM " +
                     Number(site.value("dtm_known_area_m2", json()), "%.0f") +
                     " m&sup2;; orthophoto " +
                     Number(site.value("ortho_valid_area_m2", json()), "%.0f") + " m&sup2;. ";
  if (r.value("matched", false)) {
    html += "Registration: <b>matched</b>, CC " + Number(r.value("correlation", json()), "%.3f") +
            ", peak ratio " + Number(r.value("peak_ratio", json()), "%.2f") + ", " +
            Number(r.value("control_points", json()), "%.0f") + " control points.";
  } else {
    html += "Registration: <b>no match</b> (" + Escape(r.value("reason", std::string("?"))) + ").";
  }
  html += "</p><details><summary>registration details and correlation surface</summary><pre>" +
          Escape(r.dump(2)) + "</pre>" +
          EmbeddedPng(run_dir / "sites" / folder / "correlation_surface.png", "correlation surface",
                      320) +
          "</details>";
  return html;
}

std::string LegSection(const json& leg) {
  std::string html = "<h3>Leg " + std::to_string(leg.value("site_a", -1)) + " &rarr; " +
                     std::to_string(leg.value("site_b", -1)) + "</h3><p>Outcome: <b>" +
                     Escape(leg.value("outcome", std::string("?"))) + "</b>, " +
                     Number(leg.value("tie_points", json()), "%.0f") + " tie points, RE " +
                     Number(leg.value("relative_error_percent", json()), "%.2f %%") +
                     ", telemetry distance " +
                     Number(leg.value("telemetry_distance_m", json()), "%.1f m") + ".";
  const json& first = leg.value("first_pass", json::object());
  if (first.contains("outcome")) {
    html += " First pass (a-priori tie covariances): " +
            Escape(first.value("outcome", std::string("?"))) + ", " +
            Number(first.value("tie_points", json()), "%.0f") + " tie points, RE " +
            Number(first.value("relative_error_percent", json()), "%.2f %%") +
            "; this pass scaled them by " +
            Number(leg.value("tie_variance_factor", json()), "%.3f") + ".";
  }
  html += "</p>";
  const json& checks = leg.value("faults", json::object()).value("rules", json::array());
  html +=
      "<table><tr><th>module</th><th>rule</th><th>value</th><th>threshold</th>"
      "<th>verdict</th></tr>";
  for (const json& c : checks) {
    const std::string verdict = c.value("verdict", std::string());
    html += "<tr class=\"" + Escape(verdict) + "\"><td>" + Escape(c.value("module", "")) +
            "</td><td>" + Escape(c.value("rule", "")) + "</td><td>" +
            Number(c.value("value", json()), "%.3g") + " " + Escape(c.value("unit", "")) +
            "</td><td>" + Number(c.value("threshold", json()), "%.3g") + "</td><td>" +
            Escape(verdict) + "</td></tr>";
  }
  return html + "</table>";
}

void WriteRunReportHtml(const fs::path& run_dir, const json& summary);

}  // namespace

void WriteRunReport(const fs::path& run_dir) {
  std::ifstream in(run_dir / "summary.json");
  if (!in) {
    throw Error(run_dir.string() + ": no summary.json; expected the --out folder of areomap run");
  }
  const json summary = json::parse(in, nullptr, false);
  if (summary.is_discarded() || !summary.contains("sites") || !summary.contains("legs")) {
    throw Error((run_dir / "summary.json").string() +
                ": not the summary of areomap run (expected \"sites\" and \"legs\")");
  }
  for (const char* key : {"sites", "legs"}) {
    const json& list = summary[key];
    if (!list.is_array() ||
        !std::all_of(list.begin(), list.end(), [](const json& e) { return e.is_object(); })) {
      throw Error((run_dir / "summary.json").string() + ": \"" + key + "\" is " +
                  list.dump().substr(0, 40) + "; expected an array of objects (areomap run's)");
    }
  }
  try {
    WriteRunReportHtml(run_dir, summary);
  } catch (const json::exception& e) {
    // A field of another type than areomap run writes (the summary was edited, or is foreign).
    throw Error((run_dir / "summary.json").string() +
                ": a field has another type than areomap run writes: " + e.what());
  }
}

namespace {

void WriteRunReportHtml(const fs::path& run_dir, const json& summary) {
  std::string html =
      "<!DOCTYPE html><html><head><meta charset=\"utf-8\"><title>areomap run: " +
      Escape(summary.value("name", std::string())) +
      "</title><style>body{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}"
      "table{border-collapse:collapse;margin:.5em 0;font-size:90%}td,th{border:1px solid #bbb;"
      "padding:2px 6px;text-align:right}th{background:#eee}tr.fail td{background:#fdd}"
      "table.figures th{text-align:left}pre{font-size:80%;background:#f6f6f6}</style></head><body>"
      "<h1>areomap run: " +
      Escape(summary.value("name", std::string())) + "</h1>";
  html += "<h2>Key figures</h2>" + KeyFigures(summary);
  html +=
      "<h2>Traverse</h2><p>Telemetry (red), adjusted with 1&sigma; ellipses (green, "
      "enlarged) and, when known, true (blue) positions over the orbital image.</p>" +
      EmbeddedPng(run_dir / "adjustment" / "traverse_map.png", "traverse map", 1000);
  html += "<h3>Anchored sites</h3>" + CsvTable(run_dir / "adjustment" / "sites.csv");
  html += "<h3>Legs (relative error, Tables 4.6 / 5.2)</h3>" +
          CsvTable(run_dir / "adjustment" / "legs.csv");
  html += "<h2>Orbital registration per site</h2>";
  const json guided = summary.value("guided_registration", json::object());
  if (guided.contains("registered_first_pass")) {
    html += "<p>" + std::to_string(guided["registered_first_pass"].size()) + " of " +
            std::to_string(summary["sites"].size()) +
            " sites registered around their telemetry positions";
    for (const json& pass : guided.value("passes", json::array())) {
      html += "; guided pass " + std::to_string(pass.value("pass", 0)) + " (around the adjusted " +
              "poses, " + std::to_string(pass.value("attempted", json::array()).size()) +
              " sites tried): " + std::to_string(pass.value("registered", json::array()).size()) +
              " more";
      if (const size_t replaced = pass.value("replaced", json::array()).size(); replaced > 0) {
        html += " and " + std::to_string(replaced) +
                " re-matched whose first turn was at the edge of the rotation search";
      }
    }
    html += ".</p>";
  }
  for (const json& site : summary["sites"]) {
    html +=
        SiteSection(run_dir, site) + GuidedSiteParagraph(run_dir, guided, site.value("site", -1));
  }
  html += "<h2>Tie points and fault detection per leg</h2>";
  for (const json& leg : summary["legs"]) html += LegSection(leg);
  html += ProductsSection(run_dir, summary);
  html += CratersSection(run_dir, summary);
  html += StageTimes(summary);
  html += "</body></html>\n";
  WriteFileAtomically(run_dir / "report.html", html);
}

}  // namespace

}  // namespace areomap
