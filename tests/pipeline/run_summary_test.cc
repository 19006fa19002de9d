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

// Every record set, figures that differ from each other and from the defaults.
RunSummary FullSummary() {
  RunSummary s;
  s.mission = "/missions/two_sites";
  s.name = "two sites";
  s.command = "run";
  s.seconds = 12.5;
  mission_run::SiteUnitResult site;
  site.site = 1;
  site.points = 1000;
  site.dtm_known_area_m2 = 40.0;
  site.ortho_valid_area_m2 = 38.5;
  site.registration.matched = true;
  site.registration.correlation = 0.75;
  site.registration.peak_ratio = 1.8;
  site.registration.control_points = 12;
  site.registration.other = {{"window_clipped", false}};
  site.seconds = {{"stereo", 3.5}};
  s.sites = {site};
  mission_run::LegUnitResult leg;
  leg.site_a = 0;
  leg.site_b = 1;
  leg.telemetry_distance_m = 21.6;
  leg.match.outcome = "matched";
  leg.match.tie_points = 6;
  leg.match.relative_error_percent = 1.75;
  leg.match.tie_variance_factor = 0.3;
  mission_run::LegPassRecord first;
  first.outcome = "excluded by fault detection";
  leg.first_pass = first;
  LegConsistency test;
  test.tested = true;
  test.dropped = {2, 5};
  test.first_f_statistic = 3.1;
  test.f_threshold = 2.2;
  leg.leg_test = test;
  leg.leg_test_dropped_ids = {"a", "b"};
  leg.faults.checks = {
      {"I pre-screening", "traverse length", 24.3, 30.0, "m", FaultVerdict::kPass, false}};
  s.legs = {leg};
  const mission_run::AdjustmentResult adjustment =
      mission_run::AdjustmentResult::FromJson({{"length_m", 90.4},
                                               {"sigma0", 0.39},
                                               {"tie_points", 10},
                                               {"adjusted_end_error_m", 0.02},
                                               {"sites_within_1sigma", 3},
                                               {"largest_horizontal_sigma_m", 0.1}},
                                              "adjustment");
  s.adjustment = adjustment;
  s.tie_variance = mission_run::TieVarianceRecord{3, 16, 4.8, 0.3, 0.6, std::nullopt};
  mission_run::GuidedPassRecord pass;
  pass.pass = 1;
  mission_run::GuidedAttemptRecord attempt;
  attempt.site = 3;
  attempt.matched = true;
  attempt.correlation = 0.77;
  attempt.prior = {1.0, -2.0, -4.4, 0.5};
  pass.attempted = {attempt};
  pass.registered = {3};
  pass.replaced = {4};
  s.guided = mission_run::GuidedPassesResult{{0, 1}, adjustment, {pass}};
  mission_run::ProductsUnitResult products;
  products.posting_m = 0.05;
  products.dtm_minus_orbital_adjusted =
      mission_run::TraverseDifference{128294, 0.016, 0.044, 0.04, 0.018};
  products.ortho_vs_orbital_adjusted = mission_run::TraverseCorrelation{9000, 0.54};
  products.ortho_vs_orbital_telemetry = mission_run::TraverseCorrelation{1, std::nullopt};
  s.products = products;
  mission_run::CratersUnitResult craters;
  craters.craters = 10;
  mission_run::CraterScoreRecord score;
  score.rule = "centre < 0.5 r";
  score.truth = 10;
  score.matched_truth = 10;
  score.recall = 1.0;
  score.median_center_error_px = 0.05;
  craters.score = score;
  s.craters = craters;
  s.units = UnitsSummary{0, 5, 1, 3, 2, "reused", "computed"};
  s.stage_seconds = {{"sites", 73.3}, {"legs", 10.5}};
  s.computed_seconds = {{"stereo", 117.8}};
  return s;
}

TEST(RunSummary, RoundTripsThroughJson) {
  const RunSummary s = FullSummary();
  const json written = s.ToJson();
  EXPECT_EQ(RunSummary::FromJson(written, "summary.json").ToJson(), written);
  EXPECT_EQ(RunSummary::FromJson(written, "summary.json"), s);
  // Through text too, as the file holds it, and written back as the same text.
  const std::string text = written.dump(2);
  EXPECT_EQ(RunSummary::FromJson(json::parse(text), "summary.json"), s);
  EXPECT_EQ(RunSummary::FromJson(json::parse(text), "summary.json").ToJson().dump(2), text);
  // Names as summary.json's readers (docs/summary-format.md) know them; counts as integers.
  EXPECT_EQ(written["rock_tie_variance"]["redundancy"].dump(), "16");
  EXPECT_EQ(written["sites"][0]["points"].dump(), "1000");
  EXPECT_EQ(written["legs"][0]["leg_test"]["dropped"], json::array({2, 5}));
  EXPECT_EQ(written["guided_registration"]["passes"][0]["attempted"][0]["prior"]["sigma_m"], 0.5);
  EXPECT_TRUE(written["rock_tie_variance"]["applied_factor"].is_null());
  EXPECT_EQ(written["units"]["products"], "computed");
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
  EXPECT_FALSE(mission_run::Known(s.sites[0].registration.correlation));
  EXPECT_FALSE(s.sites[0].registration.peak_ratio.has_value());
  EXPECT_EQ(s.sites[0].points, 0);  // An older summary's missing count reads as none.
  EXPECT_FALSE(s.craters.has_value());
  EXPECT_FALSE(s.products.has_value());
  ASSERT_TRUE(s.tie_variance.has_value());
  EXPECT_FALSE(s.tie_variance->applied_factor.has_value());
  EXPECT_FALSE(s.guided.has_value());
  EXPECT_FALSE(s.adjustment.has_value());
  EXPECT_FALSE(s.units.has_value());
  // Null figures read as NaN: compared as text.
  EXPECT_EQ(RunSummary::FromJson(s.ToJson(), "summary.json").ToJson().dump(), s.ToJson().dump());
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
