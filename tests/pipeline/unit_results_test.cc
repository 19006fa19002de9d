// The mission run's unit results (pipeline/src/unit_results.h): each round-trips through the JSON
// a unit records, the run's records read back as they were written, and a field of another type
// is named by its path.
#include "areomap/pipeline/unit_results.h"

#include <gtest/gtest.h>

#include <string>

#include "areomap/map/error.h"
#include "test_support.h"

namespace areomap::mission_run {
namespace {

using nlohmann::json;

SiteRegistrationResult Registration() {
  SiteRegistrationResult r;
  r.matched = true;
  r.control_points = 7;
  r.template_pixels = 52000;
  r.search_radius_px = 24;
  r.correlation = 0.75;
  r.gsd_m = 0.25;
  r.prior_sigma_m = 2.0;
  r.rotation_deg = 0.02;
  r.shift_east_m = -0.02;
  r.shift_north_m = 0.007;
  r.sigma_east_m = 0.03;
  r.sigma_north_m = 0.025;
  r.other = {{"orbital", "hirise.tif"}, {"chance_level", {{"peak_z", 48.5}}}, {"overlaps", true}};
  return r;
}

SiteUnitResult Site() {
  SiteUnitResult s;
  s.site = 3;
  s.pairs = {{"NAVCAM", 0, 0, 836866, 0, 113, 129047, 0.02, 0.80},
             {"PANCAM", 4, 1, 1000, 2, 0, 500, 0.01, 0.5}};
  s.points = 1038402;
  s.coarse_points_dropped = 12;
  s.dtm_known_area_m2 = 2726.06;
  s.ortho_valid_area_m2 = 1956.39;
  s.registration = Registration();
  s.seconds = {{"stereo", 117.8}, {"dtm", 9.5}, {"ortho", 4.3}, {"registration", 0.9}};
  return s;
}

LegUnitResult Leg() {
  LegUnitResult leg;
  leg.site_a = 1;
  leg.site_b = 2;
  leg.telemetry_distance_m = 22.4;
  leg.prior = LegPriorRecord{"orbital registration",
                             "",
                             2.3,
                             2.9,
                             std::array<double, 3>{21.6, -1.5, 0.1},
                             2.9,
                             0.09,
                             0.71};
  leg.match = {"matched", 6, 9, 1.75, 3.2, 8, 0.3, 4.1};
  leg.first_pass = LegPassRecord{
      "excluded by fault detection", 0, 1, std::nullopt, std::nullopt, std::nullopt, 1.0, 3.9};
  leg.rocks_a = {1038402, 2464, 0, 1612, 551, 301, 109};
  leg.rocks_b = {1021586, 2338, 1, 1652, 376, 310, 104};
  leg.faults.site_a = 1;
  leg.faults.site_b = 2;
  leg.faults.outcome = PairOutcome::kExcludedByFaultDetection;
  leg.faults.checks = {MaxCheck("I pre-screening", "traverse length", 21.7, 30.0, "m"),
                       MinCheck("II peaks", "peaks at site a", 310.0, 10.0, "peaks")};
  LegConsistency test;
  test.tested = true;
  test.sigma0_squared = 0.32;
  test.redundancy = 4;
  test.reference_sigma0_squared = 0.22;
  test.reference_redundancy = 8;
  test.f_statistic = 1.43;
  test.f_threshold = 14.4;
  test.first_f_statistic = 2.1;
  test.dropped = {3};
  leg.leg_test = test;
  leg.leg_test_dropped_ids = {"s001-s002-r3"};
  return leg;
}

CratersUnitResult Craters() {
  CratersUnitResult c;
  c.image = "hirise_ortho.tif";
  c.method = "combined";
  c.pixel_size_m = 0.25;
  c.min_diameter_m = 4.0;
  c.craters = 10;
  c.files = {"craters.csv", "overlay.png"};
  c.sun_azimuth_source = "manifest";
  c.sun_azimuth_deg = 120.0;
  CraterScoreRecord score;
  score.rule = "centre";
  score.truth = 10;
  score.recall = 1.0;
  score.other = {{"max_diameter_px", "inf"}};
  c.score = score;
  c.seconds = 0.64;
  return c;
}

AdjustmentResult Adjustment() {
  AdjustmentResult a;
  a.sites = 5;
  a.tie_points = 10;
  a.control_points = 50;
  a.priors = 4;
  a.rock_tie_variance_factor = 0.5;
  a.redundancy = 180;
  a.sigma0 = 0.386;
  a.converged = true;
  a.length_m = 90.4;
  a.largest_horizontal_sigma_m = 0.037;
  a.solve_seconds = 0.0025;
  a.files = {"adjustment.json", "report.txt"};
  a.initial_end_error_m = 4.6;
  a.adjusted_end_error_m = 0.02;
  a.sites_within_1sigma = 3;
  return a;
}

GuidedPassesResult Guided() {
  GuidedPassesResult g;
  g.registered_first_pass = {0, 1, 2};
  g.first_adjustment = Adjustment();
  GuidedPassRecord pass;
  pass.pass = 1;
  pass.attempted = {
      {3, {2.16, 2.67, -4.41, 0.5}, true, "", 0.77, 0.42, 6, 12, true},
      {4, {4.1, 2.0, -4.5, 0.5}, false, "below chance", std::nullopt, 0.4, 6, 0, false}};
  pass.registered = {4};
  pass.replaced = {3};
  pass.adjustment = Adjustment();
  pass.adjustment->sigma0 = 0.395;
  g.passes = {pass, GuidedPassRecord{2, {}, {}, {}, std::nullopt}};
  return g;
}

ProductsUnitResult Products() {
  ProductsUnitResult p;
  p.posting_m = 0.1;
  p.width = 900;
  p.height = 612;
  p.dtm_known_area_m2 = 8018.4;
  p.ortho_valid_area_m2 = 6355.5;
  p.files = {"traverse_dtm.tif", "traverse_ortho.tif"};
  p.poses = {{0.01, -0.006, 0.005, 1.0, 0.0, 0.0, 0.0},
             {21.6, -11.1, 0.1, 0.9997, 0.0, 0.0, 0.025}};
  p.orbital_dtm = "hirise_dtm.tif";
  p.dtm_minus_orbital_adjusted = TraverseDifference{128294, 0.016, 0.044, 0.041, 0.018};
  p.dtm_minus_orbital_telemetry = TraverseDifference{0, {}, {}, {}, {}};
  p.orbital_image = "hirise_ortho.tif";
  p.ortho_vs_orbital_adjusted = TraverseCorrelation{101688, 0.54};
  p.ortho_vs_orbital_telemetry = TraverseCorrelation{1, std::nullopt};
  p.seconds = {{"dtm", 10.0}, {"orthomosaic", 5.0}, {"comparison", 1.0}};
  return p;
}

template <typename Result>
void ExpectRoundTrip(const Result& result) {
  const json written = result.ToJson();
  const Result back = Result::FromJson(written, "unit.json: summary");
  EXPECT_EQ(back, result) << written.dump(1);
  EXPECT_EQ(back.ToJson(), written);
}

TEST(UnitResults, EveryUnitResultRoundTrips) {
  ExpectRoundTrip(Registration());
  ExpectRoundTrip(Site());
  ExpectRoundTrip(Leg());
  ExpectRoundTrip(Craters());
  ExpectRoundTrip(Adjustment());
  ExpectRoundTrip(Guided());
  ExpectRoundTrip(Products());
  GuidedUnitResult unit;
  unit.site = 4;
  unit.pass = 1;
  unit.prior = {4.1, 2.0, -4.5, 0.5};
  unit.settings = {72, 1e-3, 0.5};
  unit.registration = Registration();
  ExpectRoundTrip(unit);
}

TEST(UnitResults, SkippedStagesRoundTripAsRecorded) {
  SiteRegistrationResult skipped;
  skipped.skipped = true;
  skipped.reason = "the mission has no orbital image";
  EXPECT_EQ(skipped.ToJson(),
            (json{{"status", "skipped"}, {"reason", "the mission has no orbital image"}}));
  ExpectRoundTrip(skipped);
  CratersUnitResult craters;
  craters.skipped = true;
  craters.reason = "the mission has no orbital image";
  craters.seconds = 0.1;
  EXPECT_EQ(craters.ToJson(), (json{{"status", "skipped"},
                                    {"reason", "the mission has no orbital image"},
                                    {"seconds", 0.1}}));
  ExpectRoundTrip(craters);
}

// The crater score and the pooled tie variance as the run writes them (integers as integers,
// undefined figures null) read and written back unchanged.
TEST(UnitResults, ScoreAndTieVarianceReadBackAsWritten) {
  const json score = {{"min_diameter_px", 16.0},
                      {"max_diameter_px", "inf"},
                      {"truth", 3},
                      {"detected", 0},
                      {"matched_truth", 0},
                      {"matched_detected", 0},
                      {"precision", nullptr},
                      {"recall", 0.0},
                      {"f1", nullptr},
                      {"median_center_error_px", nullptr},
                      {"median_diameter_error", nullptr},
                      {"rule", "centre"}};
  const CraterScoreRecord read = CraterScoreRecord::FromJson(score, "score");
  EXPECT_EQ(read.truth, 3);
  EXPECT_FALSE(read.precision.has_value());
  EXPECT_EQ(read.ToJson().dump(), score.dump());
  const json ties = {{"legs", 4},
                     {"chi2", 12.5},
                     {"redundancy", 40},
                     {"sigma0_squared", 0.3125},
                     {"sigma0_squared_upper_95", nullptr},
                     {"applied_factor", nullptr}};
  const TieVarianceRecord t = TieVarianceRecord::FromJson(ties, "rock_tie_variance");
  EXPECT_EQ(t.legs, 4);
  EXPECT_FALSE(t.applied_factor.has_value());
  EXPECT_EQ(t.ToJson().dump(), ties.dump());
}

// The records as the run writes them, figures not typed and non-finite ones (null) included,
// read and written back unchanged.
TEST(UnitResults, RecordsReadBackAsTheRunWroteThem) {
  const json registration = {{"matched", false},       {"reason", "no confident peak"},
                             {"correlation", nullptr}, {"peak_ratio", nullptr},
                             {"gsd_m", 0.25},          {"search_radius_px", 24},
                             {"template_pixels", 300}, {"control_points", 0},
                             {"prior_sigma_m", 2.0},   {"window_clipped", false}};
  EXPECT_EQ(SiteRegistrationResult::FromJson(registration, "r").ToJson().dump(),
            registration.dump());
  const SiteRegistrationResult read = SiteRegistrationResult::FromJson(registration, "r");
  EXPECT_FALSE(read.Registered());
  EXPECT_EQ(read.template_pixels, 300);
  const json products = Products().ToJson();
  ProductsUnitResult summary = ProductsUnitResult::FromJson(products, "p");
  summary.poses.clear();
  EXPECT_FALSE(summary.ToJson().contains("poses"));
  EXPECT_TRUE(products.contains("poses"));
}

TEST(UnitResults, AFieldOfAnotherTypeIsNamedByItsPath) {
  json site = Site().ToJson();
  site["registration"]["matched"] = "yes";
  EXPECT_EQ(testing::ErrorMessageOf(
                [&] { SiteUnitResult::FromJson(site, "sites/site_003/unit.json: summary"); }),
            "sites/site_003/unit.json: summary.registration.matched is \"yes\"; expected true or "
            "false (the type areomap run writes)");
  json leg = Leg().ToJson();
  leg["faults"]["rules"][1]["value"] = "x";
  EXPECT_NE(testing::ErrorMessageOf([&] {
              LegUnitResult::FromJson(leg, "leg");
            }).find("leg.faults.rules[1].value is \"x\"; expected a number"),
            std::string::npos);
  json guided = Guided().ToJson();
  guided["passes"][0]["attempted"][1]["control_points"] = 1.5;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              GuidedPassesResult::FromJson(guided, "g");
            }).find("g.passes[0].attempted[1].control_points is 1.5; expected an integer"),
            std::string::npos);
  json products = Products().ToJson();
  products["poses"][1] = {1.0, 2.0};
  EXPECT_NE(testing::ErrorMessageOf([&] {
              ProductsUnitResult::FromJson(products, "p");
            }).find("p.poses is [1.0,2.0]; expected arrays of 7 numbers"),
            std::string::npos);
  EXPECT_NE(testing::ErrorMessageOf([&] {
              CratersUnitResult::FromJson(json::array(), "c");
            }).find("c is []; expected an object"),
            std::string::npos);
  json adjustment = Adjustment().ToJson();
  adjustment["converged"] = 1;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              AdjustmentResult::FromJson(adjustment, "a");
            }).find("a.converged is 1; expected true or false"),
            std::string::npos);
}

}  // namespace
}  // namespace areomap::mission_run
