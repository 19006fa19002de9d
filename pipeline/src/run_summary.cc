#include "areomap/pipeline/run_summary.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "areomap/map/error.h"
#include "json_fields.h"

namespace areomap {
namespace {

using nlohmann::json;

using json_fields::Fields;
using json_fields::Put;

SiteSummary ReadSite(const Fields& f) {
  SiteSummary s;
  s.site = f.Integer("site", -1);
  s.points = f.Number("points");
  s.dtm_known_area_m2 = f.Number("dtm_known_area_m2");
  s.ortho_valid_area_m2 = f.Number("ortho_valid_area_m2");
  if (const std::optional<Fields> r = f.Object("registration")) {
    s.registration.matched = r->Flag("matched", false);
    s.registration.reason = r->Text("reason", "?");
    s.registration.correlation = r->Number("correlation");
    s.registration.peak_ratio = r->Number("peak_ratio");
    s.registration.control_points = r->Number("control_points");
    s.registration.record = r->object();
  }
  return s;
}

LegSummary ReadLeg(const Fields& f) {
  LegSummary leg;
  leg.site_a = f.Integer("site_a", -1);
  leg.site_b = f.Integer("site_b", -1);
  leg.outcome = f.Text("outcome", "?");
  leg.tie_points = f.Integer("tie_points", 0);
  leg.relative_error_percent = f.Number("relative_error_percent");
  leg.telemetry_distance_m = f.Number("telemetry_distance_m");
  leg.tie_variance_factor = f.Number("tie_variance_factor");
  if (const std::optional<Fields> first = f.Object("first_pass"); first && first->Has("outcome")) {
    leg.first_pass = LegFirstPassSummary{first->Text("outcome", "?"), first->Number("tie_points"),
                                         first->Number("relative_error_percent")};
  }
  if (const std::optional<Fields> test = f.Object("leg_test")) {
    leg.leg_test.tested = test->Flag("tested", false);
    leg.leg_test.dropped = test->Integers("dropped");
    leg.leg_test.first_f_statistic = test->Number("first_f_statistic");
    leg.leg_test.f_threshold = test->Number("f_threshold");
  }
  if (const std::optional<Fields> faults = f.Object("faults")) {
    for (size_t i = 0; i < faults->Array("rules").size(); ++i) {
      const Fields r = faults->Element("rules", i);
      leg.rules.push_back({r.Text("module", ""), r.Text("rule", ""), r.Text("unit", ""),
                           r.Text("verdict", ""), r.Number("value"), r.Number("threshold")});
    }
  }
  return leg;
}

AdjustmentSummary ReadAdjustment(const Fields& f) {
  AdjustmentSummary a;
  a.length_m = f.Number("length_m");
  a.sigma0 = f.Number("sigma0");
  a.tie_points = f.Number("tie_points");
  a.control_points = f.Number("control_points");
  a.rejected = f.Number("rejected");
  a.sites = f.Number("sites");
  a.initial_end_error_m = f.Number("initial_end_error_m");
  a.adjusted_end_error_m = f.Number("adjusted_end_error_m");
  a.median_adjusted_leg_re = f.Number("median_adjusted_leg_re");
  a.largest_horizontal_sigma_m = f.Number("largest_horizontal_sigma_m");
  a.median_adjusted_error_m = f.Number("median_adjusted_error_m");
  a.worst_adjusted_error_m = f.Number("worst_adjusted_error_m");
  a.sites_within_1sigma = f.Number("sites_within_1sigma");
  return a;
}

TieVarianceSummary ReadTieVariance(const Fields& f) {
  return {f.Number("sigma0_squared"), f.Number("sigma0_squared_upper_95"), f.Number("legs"),
          f.Number("redundancy"), f.Number("applied_factor")};
}

GuidedSummary ReadGuided(const Fields& f) {
  GuidedSummary g;
  if (f.Has("registered_first_pass")) g.registered_first_pass = f.Integers("registered_first_pass");
  for (size_t i = 0; i < f.Array("passes").size(); ++i) {
    const Fields p = f.Element("passes", i);
    GuidedPassSummary pass;
    pass.pass = p.Integer("pass", 0);
    pass.registered = p.Integers("registered");
    pass.replaced = p.Integers("replaced");
    for (size_t k = 0; k < p.Array("attempted").size(); ++k) {
      const Fields a = p.Element("attempted", k);
      GuidedAttemptSummary attempt;
      attempt.site = a.Integer("site", -1);
      attempt.matched = a.Flag("matched", false);
      attempt.reason = a.Text("reason", "?");
      attempt.correlation = a.Number("correlation");
      attempt.null_highest_correlation = a.Number("null_highest_correlation");
      attempt.control_points = a.Number("control_points");
      attempt.search_radius_px = a.Number("search_radius_px");
      if (const std::optional<Fields> prior = a.Object("prior")) {
        attempt.prior_rotation_deg = prior->Number("rotation_deg");
        attempt.prior_sigma_m = prior->Number("sigma_m");
      }
      pass.attempted.push_back(attempt);
    }
    g.passes.push_back(pass);
  }
  return g;
}

ProductsSummary ReadProducts(const Fields& f) {
  ProductsSummary p;
  p.posting_m = f.Number("posting_m");
  p.dtm_known_area_m2 = f.Number("dtm_known_area_m2");
  p.ortho_valid_area_m2 = f.Number("ortho_valid_area_m2");
  const auto difference = [&](const char* key) -> std::optional<DifferenceSummary> {
    const std::optional<Fields> d = f.Object(key);
    if (!d) return std::nullopt;
    return DifferenceSummary{d->Number("cells"), d->Number("mean_m"), d->Number("stddev_m"),
                             d->Number("rms_m"), d->Number("median_abs_m")};
  };
  p.dtm_minus_orbital_adjusted = difference("dtm_minus_orbital_adjusted");
  p.dtm_minus_orbital_telemetry = difference("dtm_minus_orbital_telemetry");
  const auto correlation = [&](const char* key) -> std::optional<OptionalNumber> {
    const std::optional<Fields> c = f.Object(key);
    if (!c) return std::nullopt;
    return c->Number("correlation");
  };
  p.ortho_vs_orbital_adjusted = correlation("ortho_vs_orbital_adjusted");
  p.ortho_vs_orbital_telemetry = correlation("ortho_vs_orbital_telemetry");
  return p;
}

CratersSummary ReadCraters(const Fields& f) {
  CratersSummary c;
  c.craters = f.Number("craters");
  c.min_diameter_m = f.Number("min_diameter_m");
  if (const std::optional<Fields> s = f.Object("score")) {
    c.score = CraterScoreSummary{s->Text("rule", ""),        s->Number("truth"),
                                 s->Number("matched_truth"), s->Number("precision"),
                                 s->Number("recall"),        s->Number("median_center_error_px")};
  }
  return c;
}

std::map<std::string, double> ReadSeconds(const Fields& f, const char* key) {
  std::map<std::string, double> out;
  if (const std::optional<Fields> seconds = f.Object(key)) {
    for (const auto& [stage, value] : seconds->object().items()) {
      if (const OptionalNumber v = seconds->Number(stage.c_str())) out[stage] = *v;
    }
  }
  return out;
}

json SiteToJson(const SiteSummary& s) {
  json registration = s.registration.record;
  registration["matched"] = s.registration.matched;
  registration["reason"] = s.registration.reason;
  Put(registration, "correlation", s.registration.correlation);
  Put(registration, "peak_ratio", s.registration.peak_ratio);
  Put(registration, "control_points", s.registration.control_points);
  json j = {{"site", s.site}, {"registration", registration}};
  Put(j, "points", s.points);
  Put(j, "dtm_known_area_m2", s.dtm_known_area_m2);
  Put(j, "ortho_valid_area_m2", s.ortho_valid_area_m2);
  return j;
}

json LegToJson(const LegSummary& leg) {
  json rules = json::array();
  for (const FaultRuleSummary& r : leg.rules) {
    json rule = {{"module", r.module}, {"rule", r.rule}, {"unit", r.unit}, {"verdict", r.verdict}};
    Put(rule, "value", r.value);
    Put(rule, "threshold", r.threshold);
    rules.push_back(rule);
  }
  json test = {{"tested", leg.leg_test.tested}, {"dropped", leg.leg_test.dropped}};
  Put(test, "first_f_statistic", leg.leg_test.first_f_statistic);
  Put(test, "f_threshold", leg.leg_test.f_threshold);
  json j = {{"site_a", leg.site_a},         {"site_b", leg.site_b}, {"outcome", leg.outcome},
            {"tie_points", leg.tie_points}, {"leg_test", test},     {"faults", {{"rules", rules}}}};
  Put(j, "relative_error_percent", leg.relative_error_percent);
  Put(j, "telemetry_distance_m", leg.telemetry_distance_m);
  Put(j, "tie_variance_factor", leg.tie_variance_factor);
  if (leg.first_pass) {
    json first = {{"outcome", leg.first_pass->outcome}};
    Put(first, "tie_points", leg.first_pass->tie_points);
    Put(first, "relative_error_percent", leg.first_pass->relative_error_percent);
    j["first_pass"] = first;
  }
  return j;
}

json AdjustmentToJson(const AdjustmentSummary& a) {
  json j = json::object();
  Put(j, "length_m", a.length_m);
  Put(j, "sigma0", a.sigma0);
  Put(j, "tie_points", a.tie_points);
  Put(j, "control_points", a.control_points);
  Put(j, "rejected", a.rejected);
  Put(j, "sites", a.sites);
  Put(j, "initial_end_error_m", a.initial_end_error_m);
  Put(j, "adjusted_end_error_m", a.adjusted_end_error_m);
  Put(j, "median_adjusted_leg_re", a.median_adjusted_leg_re);
  Put(j, "largest_horizontal_sigma_m", a.largest_horizontal_sigma_m);
  Put(j, "median_adjusted_error_m", a.median_adjusted_error_m);
  Put(j, "worst_adjusted_error_m", a.worst_adjusted_error_m);
  Put(j, "sites_within_1sigma", a.sites_within_1sigma);
  return j;
}

json GuidedToJson(const GuidedSummary& g) {
  json passes = json::array();
  for (const GuidedPassSummary& p : g.passes) {
    json attempted = json::array();
    for (const GuidedAttemptSummary& a : p.attempted) {
      json prior = json::object();
      Put(prior, "rotation_deg", a.prior_rotation_deg);
      Put(prior, "sigma_m", a.prior_sigma_m);
      json j = {{"site", a.site}, {"matched", a.matched}, {"reason", a.reason}, {"prior", prior}};
      Put(j, "correlation", a.correlation);
      Put(j, "null_highest_correlation", a.null_highest_correlation);
      Put(j, "control_points", a.control_points);
      Put(j, "search_radius_px", a.search_radius_px);
      attempted.push_back(j);
    }
    passes.push_back({{"pass", p.pass},
                      {"attempted", attempted},
                      {"registered", p.registered},
                      {"replaced", p.replaced}});
  }
  json j = {{"passes", passes}};
  if (g.registered_first_pass) j["registered_first_pass"] = *g.registered_first_pass;
  return j;
}

json ProductsToJson(const ProductsSummary& p) {
  json j = json::object();
  Put(j, "posting_m", p.posting_m);
  Put(j, "dtm_known_area_m2", p.dtm_known_area_m2);
  Put(j, "ortho_valid_area_m2", p.ortho_valid_area_m2);
  const auto difference = [&](const char* key, const std::optional<DifferenceSummary>& d) {
    if (!d) return;
    json stats = json::object();
    Put(stats, "cells", d->cells);
    Put(stats, "mean_m", d->mean_m);
    Put(stats, "stddev_m", d->stddev_m);
    Put(stats, "rms_m", d->rms_m);
    Put(stats, "median_abs_m", d->median_abs_m);
    j[key] = stats;
  };
  difference("dtm_minus_orbital_adjusted", p.dtm_minus_orbital_adjusted);
  difference("dtm_minus_orbital_telemetry", p.dtm_minus_orbital_telemetry);
  const auto correlation = [&](const char* key, const std::optional<OptionalNumber>& c) {
    if (!c) return;
    j[key] = json::object();
    Put(j[key], "correlation", *c);
  };
  correlation("ortho_vs_orbital_adjusted", p.ortho_vs_orbital_adjusted);
  correlation("ortho_vs_orbital_telemetry", p.ortho_vs_orbital_telemetry);
  return j;
}

json CratersToJson(const CratersSummary& c) {
  json j = json::object();
  Put(j, "craters", c.craters);
  Put(j, "min_diameter_m", c.min_diameter_m);
  if (c.score) {
    json score = {{"rule", c.score->rule}};
    Put(score, "truth", c.score->truth);
    Put(score, "matched_truth", c.score->matched_truth);
    Put(score, "precision", c.score->precision);
    Put(score, "recall", c.score->recall);
    Put(score, "median_center_error_px", c.score->median_center_error_px);
    j["score"] = score;
  }
  return j;
}

}  // namespace

RunSummary RunSummary::FromJson(const json& json_in, const std::string& source) {
  if (!json_in.is_object() || !json_in.contains("sites") || !json_in.contains("legs")) {
    throw Error(source + ": not the summary of areomap run (expected \"sites\" and \"legs\")");
  }
  for (const char* key : {"sites", "legs"}) {
    const json& list = json_in.at(key);
    if (!list.is_array() ||
        !std::all_of(list.begin(), list.end(), [](const json& e) { return e.is_object(); })) {
      throw Error(source + ": \"" + key + "\" is " + list.dump().substr(0, 40) +
                  "; expected an array of objects (areomap run's)");
    }
  }
  const Fields f(json_in, source + ":");
  RunSummary s;
  s.name = f.Text("name", "");
  s.seconds = f.Number("seconds");
  for (size_t i = 0; i < f.Array("sites").size(); ++i)
    s.sites.push_back(ReadSite(f.Element("sites", i)));
  for (size_t i = 0; i < f.Array("legs").size(); ++i)
    s.legs.push_back(ReadLeg(f.Element("legs", i)));
  if (const std::optional<Fields> a = f.Object("adjustment")) s.adjustment = ReadAdjustment(*a);
  if (const std::optional<Fields> t = f.Object("rock_tie_variance")) {
    s.tie_variance = ReadTieVariance(*t);
  }
  if (const std::optional<Fields> g = f.Object("guided_registration")) s.guided = ReadGuided(*g);
  if (const std::optional<Fields> p = f.Object("products")) s.products = ReadProducts(*p);
  if (const std::optional<Fields> c = f.Object("craters")) s.craters = ReadCraters(*c);
  if (const std::optional<Fields> u = f.Object("units")) {
    s.units = UnitsSummary{u->Integer("sites_computed", 0), u->Integer("sites_reused", 0),
                           u->Integer("legs_computed", 0), u->Integer("legs_reused", 0),
                           u->Integer("legs_rematched", 0)};
  }
  s.stage_seconds = ReadSeconds(f, "stage_seconds");
  s.computed_seconds = ReadSeconds(f, "computed_seconds");
  return s;
}

json RunSummary::ToJson() const {
  json j = {{"name", name},
            {"sites", json::array()},
            {"legs", json::array()},
            {"adjustment", AdjustmentToJson(adjustment)},
            {"guided_registration", GuidedToJson(guided)},
            {"stage_seconds", stage_seconds},
            {"computed_seconds", computed_seconds}};
  Put(j, "seconds", seconds);
  for (const SiteSummary& s : sites) j["sites"].push_back(SiteToJson(s));
  for (const LegSummary& leg : legs) j["legs"].push_back(LegToJson(leg));
  json ties = json::object();
  Put(ties, "sigma0_squared", tie_variance.sigma0_squared);
  Put(ties, "sigma0_squared_upper_95", tie_variance.sigma0_squared_upper_95);
  Put(ties, "legs", tie_variance.legs);
  Put(ties, "redundancy", tie_variance.redundancy);
  Put(ties, "applied_factor", tie_variance.applied_factor);
  j["rock_tie_variance"] = ties;
  if (products) j["products"] = ProductsToJson(*products);
  if (craters) j["craters"] = CratersToJson(*craters);
  if (units) {
    j["units"] = {{"sites_computed", units->sites_computed},
                  {"sites_reused", units->sites_reused},
                  {"legs_computed", units->legs_computed},
                  {"legs_reused", units->legs_reused},
                  {"legs_rematched", units->legs_rematched}};
  }
  return j;
}

RunSummary ReadRunSummary(const std::filesystem::path& out_dir) {
  const std::filesystem::path path = out_dir / "summary.json";
  std::ifstream in(path);
  if (!in)
    throw Error(out_dir.string() + ": no summary.json; expected the --out folder of areomap run");
  const json summary = json::parse(in, nullptr, false);
  if (summary.is_discarded()) {
    throw Error(path.string() +
                ": not the summary of areomap run (expected \"sites\" and \"legs\")");
  }
  return RunSummary::FromJson(summary, path.string());
}

}  // namespace areomap
