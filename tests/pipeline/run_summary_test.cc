// RunSummary (run_summary.h): summary.json's typed form round-trips, optional figures stay
// optional, and a field of another type is named.
#include "areomap/pipeline/run_summary.h"

#include <gtest/gtest.h>

#include <string>

#include "areomap/map/error.h"
#include "test_support.h"

namespace areomap {
namespace {

using nlohmann::json;

// Every field set, figures that differ from each other and from the defaults.
RunSummary FullSummary() {
  RunSummary s;
  s.name = "two sites";
  s.seconds = 12.5;
  SiteSummary site;
  site.site = 1;
  site.points = 1000;
  site.dtm_known_area_m2 = 40.0;
  site.ortho_valid_area_m2 = 38.5;
  // The record holds every figure of registration.json, the typed ones included.
  site.registration = {true,
                       "",
                       0.75,
                       1.8,
                       12.0,
                       json{{"gsd_m", 0.25},
                            {"matched", true},
                            {"reason", ""},
                            {"correlation", 0.75},
                            {"peak_ratio", 1.8},
                            {"control_points", 12.0}}};
  s.sites = {site};
  LegSummary leg;
  leg.site_a = 0;
  leg.site_b = 1;
  leg.outcome = "matched";
  leg.tie_points = 6;
  leg.relative_error_percent = 1.75;
  leg.telemetry_distance_m = 21.6;
  leg.tie_variance_factor = 0.3;
  leg.first_pass = LegFirstPassSummary{"excluded by fault detection", 0.0, std::nullopt};
  leg.leg_test = {true, {2, 5}, 3.1, 2.2};
  leg.rules = {{"I pre-screening", "traverse length", "m", "pass", 24.3, 30.0}};
  s.legs = {leg};
  s.adjustment.length_m = 90.4;
  s.adjustment.sigma0 = 0.39;
  s.adjustment.tie_points = 10;
  s.adjustment.adjusted_end_error_m = 0.02;
  s.adjustment.sites_within_1sigma = 3;
  s.tie_variance = {0.3, 0.6, 3.0, 16.0, std::nullopt};
  GuidedPassSummary pass;
  pass.pass = 1;
  pass.attempted = {{3, true, "", 0.77, 0.42, 12.0, 6.0, -4.4, 0.5}};
  pass.registered = {3};
  pass.replaced = {4};
  s.guided.registered_first_pass = std::vector<int>{0, 1};
  s.guided.passes = {pass};
  ProductsSummary products;
  products.posting_m = 0.05;
  products.dtm_minus_orbital_adjusted = DifferenceSummary{128294.0, 0.016, 0.04, 0.044, 0.018};
  products.ortho_vs_orbital_adjusted = OptionalNumber(0.54);
  products.ortho_vs_orbital_telemetry = OptionalNumber();  // Recorded, but no overlap.
  s.products = products;
  CratersSummary craters;
  craters.craters = 10;
  craters.score = CraterScoreSummary{"centre < 0.5 r", 10.0, 10.0, std::nullopt, 1.0, 0.05};
  s.craters = craters;
  s.units = UnitsSummary{0, 5, 1, 3, 2};
  s.stage_seconds = {{"sites", 73.3}, {"legs", 10.5}};
  s.computed_seconds = {{"stereo", 117.8}};
  return s;
}

TEST(RunSummary, RoundTripsThroughJson) {
  const RunSummary s = FullSummary();
  const json written = s.ToJson();
  EXPECT_EQ(RunSummary::FromJson(written, "summary.json").ToJson(), written);
  EXPECT_EQ(RunSummary::FromJson(written, "summary.json"), s);
  // Through text too, as the file holds it.
  EXPECT_EQ(RunSummary::FromJson(json::parse(written.dump(2)), "summary.json"), s);
  // Names as summary.json's readers (docs/summary-format.md) know them.
  EXPECT_EQ(written["rock_tie_variance"]["redundancy"], 16.0);
  EXPECT_EQ(written["legs"][0]["leg_test"]["dropped"], json::array({2, 5}));
  EXPECT_EQ(written["guided_registration"]["passes"][0]["attempted"][0]["prior"]["sigma_m"], 0.5);
  EXPECT_FALSE(written["rock_tie_variance"].contains("applied_factor"));
}

TEST(RunSummary, MissingFiguresStayMissing) {
  const RunSummary s =
      RunSummary::FromJson(json::parse(R"({"sites": [{"site": 0, "registration": {"matched": false,
        "reason": "no overlap", "correlation": null}}], "legs": [], "craters": null,
        "products": null, "rock_tie_variance": {"applied_factor": null}})"),
                           "summary.json");
  ASSERT_EQ(s.sites.size(), 1u);
  EXPECT_FALSE(s.sites[0].registration.matched);
  EXPECT_EQ(s.sites[0].registration.reason, "no overlap");
  EXPECT_FALSE(s.sites[0].registration.correlation.has_value());
  EXPECT_FALSE(s.sites[0].points.has_value());
  EXPECT_FALSE(s.craters.has_value());
  EXPECT_FALSE(s.products.has_value());
  EXPECT_FALSE(s.tie_variance.applied_factor.has_value());
  EXPECT_FALSE(s.guided.registered_first_pass.has_value());
  EXPECT_EQ(RunSummary::FromJson(s.ToJson(), "summary.json"), s);
}

TEST(RunSummary, NamesAFieldOfAnotherType) {
  const auto message = [](const std::string& text) {
    return testing::ErrorMessageOf([&] { RunSummary::FromJson(json::parse(text), "s.json"); });
  };
  std::string m = message(R"({"sites": [{"registration": {"correlation": "high"}}], "legs": []})");
  EXPECT_NE(m.find("s.json:.sites[0].registration.correlation is \"high\"; expected a number"),
            std::string::npos)
      << m;
  m = message(R"({"sites": [], "legs": [{"faults": {"rules": [3]}}]})");
  EXPECT_NE(m.find("s.json:.legs[0].faults.rules[0] is 3; expected an object"), std::string::npos)
      << m;
  m = message(R"({"sites": "x", "legs": []})");
  EXPECT_NE(m.find("s.json: \"sites\" is \"x\"; expected an array of objects"), std::string::npos)
      << m;
  m = message(R"({"legs": []})");
  EXPECT_NE(m.find("not the summary of areomap run"), std::string::npos) << m;
}

}  // namespace
}  // namespace areomap
