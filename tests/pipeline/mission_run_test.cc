// The end-to-end run on a small generated mission: every unit's products (sites, legs, craters,
// the whole-traverse DTM and orthomosaic), the report, and resuming (finished units reused, a
// removed unit recomputed alone).
#include "areomap/pipeline/mission_run.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numbers>
#include <sstream>
#include <vector>

#include <gtest/gtest.h>

#include "areomap/map/dtm.h"
#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/pipeline/mission_jobs.h"
#include "areomap/pipeline/run_report.h"
#include "areomap/pipeline/run_summary.h"
#include "areomap/pipeline/unit_results.h"
#include "areomap/samples/mission.h"
#include "test_support.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

MissionOptions TinyMission() {
  MissionOptions o = MissionOptions::Preset("demo");
  o.scene.half_extent_m = 40.0;
  o.scene.crater_count = 1;
  o.traverse.site_count = 2;
  o.traverse.min_leg_m = 8.0;
  o.traverse.max_leg_m = 10.0;
  o.navcam_pairs = 1;
  o.navcam.width = 256;
  o.navcam.height = 256;
  o.pancam_pairs = 0;
  o.render.near_radius_m = 2.0;
  o.render.mid_radius_m = 8.0;
  return o;
}

// TinyMission generated in `dir`/mission, read.
MissionManifest TinyMissionIn(const fs::path& dir) {
  GenerateMission(TinyMission(), dir / "mission");
  return ReadMissionManifest(dir / "mission");
}

// Stereo ranges for TinyMission's short legs.
MissionRunOptions TinyRunOptions() {
  MissionRunOptions options;
  options.stereo.min_range_m = 2.0;
  return options;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream buffer;
  buffer << in.rdbuf();
  return buffer.str();
}

// The unit's record (unit.json's "summary") read into its typed result (unit_results.h) writes
// back as it was.
template <typename Result>
void ExpectUnitReadsBack(const fs::path& unit_dir) {
  const nlohmann::json summary = nlohmann::json::parse(ReadText(unit_dir / "unit.json"))["summary"];
  EXPECT_EQ(Result::FromJson(summary, "unit.json: summary").ToJson().dump(), summary.dump())
      << unit_dir;
}

TEST(MissionRun, WritesEveryUnitAndResumes) {
  testing::TempDir dir;
  const MissionManifest mission = TinyMissionIn(dir.path());
  const fs::path out = dir.path() / "run";
  MissionRunOptions options = TinyRunOptions();

  const MissionRunSummary first = RunMission(mission, out, options);
  EXPECT_EQ(first.sites_computed, 2);
  EXPECT_EQ(first.legs_computed, 1);
  for (const char* file : {"points.ply", "dtm.tif", "ortho.tif", "registration.json",
                           "control_points.json", "unit.json"}) {
    EXPECT_TRUE(fs::exists(out / "sites" / "site_001" / file)) << file;
  }
  for (const char* file : {"faults.json", "tie_points.json", "unit.json"}) {
    EXPECT_TRUE(fs::exists(out / "legs" / "leg_000_001" / file)) << file;
  }
  EXPECT_TRUE(fs::exists(out / "adjustment" / "sites.csv"));
  EXPECT_GT(first.json["sites"][1]["points"].get<int>(), 200);  // Stereo produced a cloud.
  // The leg's rock search prior: orbital registration when both sites registered confidently
  // and agree with telemetry, else telemetry; always with its sigmas.
  const nlohmann::json leg = nlohmann::json::parse(
      ReadText(out / "legs" / "leg_000_001" / "unit.json"))["summary"]["prior"];
  const std::string source = leg.value("source", "");
  EXPECT_TRUE(source == "telemetry" || source == "orbital registration") << leg.dump();
  EXPECT_GT(leg.value("position_sigma_m", 0.0), 0.0) << leg.dump();
  EXPECT_GT(leg.value("heading_sigma_deg", 0.0), 0.0) << leg.dump();
  // One leg: nothing to test it against (leg_consistency.h); the verdict says so.
  EXPECT_EQ(first.json["legs"][0]["leg_test"], nlohmann::json({{"tested", false}}));
  // The legs' conformal-fit residuals pooled into the run's a-posteriori variance factor: with
  // redundancy, sum chi2 / sum redundancy; else null.
  const nlohmann::json& ties = first.json["rock_tie_variance"];
  EXPECT_EQ(first.json["legs"][0].value("tie_variance_factor", 0.0), 1.0);
  if (ties.value("redundancy", -1) > 0) {
    EXPECT_NEAR(ties["sigma0_squared"].get<double>(),
                ties["chi2"].get<double>() / ties["redundancy"].get<double>(), 1e-12);
    EXPECT_GT(ties["sigma0_squared_upper_95"].get<double>(), ties["sigma0_squared"].get<double>());
  } else {
    EXPECT_EQ(ties.value("redundancy", -1), 0) << ties.dump();
    EXPECT_TRUE(ties["sigma0_squared"].is_null()) << ties.dump();
  }

  // Whole-traverse products: GeoTIFFs on the mission map at the traverse posting, covering at
  // least what each site's own DTM covers.
  EXPECT_EQ(first.json["units"]["products"], "computed");
  const Dtm traverse = ReadDtm(out / "products" / "traverse_dtm.tif");
  EXPECT_DOUBLE_EQ(traverse.layers.grid.posting, options.traverse_posting_m);
  EXPECT_FALSE(traverse.crs_wkt.empty());
  const double cell_area = options.traverse_posting_m * options.traverse_posting_m;
  for (const auto& site : first.json["sites"]) {
    EXPECT_GE(traverse.layers.known_cells * cell_area + cell_area * 8,
              site["dtm_known_area_m2"].get<double>());
  }
  EXPECT_GT(ReadOrthophoto(out / "products" / "traverse_ortho.tif").valid_cells, 0);
  for (const char* file : {"traverse_dtm.png", "traverse_ortho.png"}) {
    EXPECT_TRUE(fs::exists(out / "products" / file)) << file;
  }
  EXPECT_GT(first.json["products"]["dtm_minus_orbital_adjusted"]["cells"].get<int>(), 0);
  // Craters: the mission's one crater is found and scored against truth/craters.csv.
  EXPECT_TRUE(fs::exists(out / "craters" / "craters.csv"));
  EXPECT_TRUE(fs::exists(out / "craters" / "overlay.png"));
  EXPECT_EQ(first.json["craters"]["score"]["truth"].get<int>(), 1);
  EXPECT_EQ(first.json["craters"]["score"]["matched_truth"].get<int>(), 1);
  EXPECT_EQ(first.json["craters"]["sun_azimuth_source"], "manifest");
  for (const char* stage : {"sites", "legs", "craters", "adjustment", "products"}) {
    EXPECT_GE(first.json["stage_seconds"][stage].get<double>(), 0.0) << stage;
  }
  EXPECT_GT(first.json["computed_seconds"]["stereo"].get<double>(), 0.0);
  EXPECT_GT(first.json["computed_seconds"]["products"].get<double>(), 0.0);
  ExpectUnitReadsBack<mission_run::SiteUnitResult>(out / "sites" / "site_001");
  ExpectUnitReadsBack<mission_run::LegUnitResult>(out / "legs" / "leg_000_001");
  ExpectUnitReadsBack<mission_run::CratersUnitResult>(out / "craters");
  ExpectUnitReadsBack<mission_run::ProductsUnitResult>(out / "products");

  // The typed summary (run_summary.h) holds what the report reads, and round-trips.
  const RunSummary typed = RunSummary::FromJson(first.json, "summary.json");
  ASSERT_EQ(typed.sites.size(), first.json["sites"].size());
  EXPECT_EQ(typed.legs.size(), first.json["legs"].size());
  ASSERT_TRUE(typed.adjustment.has_value());
  EXPECT_EQ(typed.adjustment->sigma0, first.json["adjustment"]["sigma0"].get<double>());
  ASSERT_TRUE(typed.craters && typed.craters->score);
  EXPECT_EQ(typed.craters->score->truth, 1.0);
  ASSERT_TRUE(typed.units.has_value());
  EXPECT_EQ(typed.units->sites_computed, first.sites_computed);
  EXPECT_EQ(typed.units->craters, "computed");
  // Read back and written again, the summary is the same text (integers stay integers).
  EXPECT_EQ(typed.ToJson().dump(2), first.json.dump(2));
  EXPECT_EQ(first.record.ToJson().dump(2), first.json.dump(2));

  std::ofstream(out / "summary.json") << first.json.dump();
  WriteRunReport(out);
  const std::string html = ReadText(out / "report.html");
  EXPECT_NE(html.find("Leg 0 &rarr; 1"), std::string::npos);
  // The leg's fault report, one row per rule (PairFaultReport::ToJson's "rules").
  EXPECT_NE(html.find("<td>traverse length</td>"), std::string::npos);
  EXPECT_NE(html.find("data:image/png;base64,"), std::string::npos);
  EXPECT_NE(html.find("Traverse DTM and orthomosaic"), std::string::npos);
  EXPECT_NE(html.find("Craters on the orbital image"), std::string::npos);
  EXPECT_NE(html.find("Run time per stage"), std::string::npos);
  EXPECT_NE(html.find("rock tie fits: pooled sigma0"), std::string::npos);

  // A second run reuses everything; removing one site's marker recomputes that site alone.
  const MissionRunSummary second = RunMission(mission, out, options);
  EXPECT_EQ(second.sites_reused, 2);
  EXPECT_EQ(second.legs_reused, 1);
  EXPECT_EQ(second.json["units"]["products"], "reused");
  EXPECT_EQ(second.json["units"]["craters"], "reused");
  EXPECT_EQ(second.json["rock_tie_variance"], first.json["rock_tie_variance"]);
  // A resumed run still reports what its reused units cost when they were computed.
  EXPECT_DOUBLE_EQ(second.json["computed_seconds"]["stereo"].get<double>(),
                   first.json["computed_seconds"]["stereo"].get<double>());
  // A finished site whose points.ply the user deleted runs again, alone, rather than failing
  // the legs and products that read it.
  const std::string points_before = ReadText(out / "sites" / "site_000" / "points.ply");
  ASSERT_TRUE(fs::remove(out / "sites" / "site_000" / "points.ply"));
  const MissionRunSummary recomputed = RunMission(mission, out, options);
  EXPECT_EQ(recomputed.sites_computed, 1);
  EXPECT_EQ(recomputed.sites_reused, 1);
  EXPECT_EQ(recomputed.legs_reused, 1);
  EXPECT_EQ(ReadText(out / "sites" / "site_000" / "points.ply"), points_before);
  fs::remove(out / "sites" / "site_001" / "unit.json");
  // Products made with other poses (here: recorded 1 cm off) are made again.
  nlohmann::json products_unit = nlohmann::json::parse(ReadText(out / "products" / "unit.json"));
  products_unit["summary"]["poses"][1][0] =
      products_unit["summary"]["poses"][1][0].get<double>() + 0.01;
  std::ofstream(out / "products" / "unit.json") << products_unit.dump();
  const MissionRunSummary third = RunMission(mission, out, options);
  EXPECT_EQ(third.sites_computed, 1);
  EXPECT_EQ(third.sites_reused, 1);
  EXPECT_EQ(third.json["units"]["products"], "computed");
  // Different options invalidate the finished units (the whole-run stages off, to stay fast).
  options.point_spacing_m = 0.03;
  options.detect_craters = false;
  options.traverse_products = false;
  const MissionRunSummary fourth = RunMission(mission, out, options);
  EXPECT_EQ(fourth.sites_computed, 2);

  // Guided re-registration: the tiny sites' orthophotos are too small to register at all, and a
  // prior cannot change that, so no guided pass runs.
  const nlohmann::json& guided = fourth.json["guided_registration"];
  EXPECT_TRUE(guided["registered_first_pass"].empty()) << guided.dump();
  EXPECT_TRUE(guided["passes"].empty()) << guided.dump();
  EXPECT_TRUE(guided.contains("first_adjustment"));

  // A changed input file (one label rewritten: its modification time moves) makes every unit
  // run again; the same options alone would reuse them all.
  const fs::path label = mission.sites.back().pairs.front().left_label;
  ASSERT_FALSE(label.empty());
  fs::last_write_time(label, fs::last_write_time(label) + std::chrono::seconds(1));
  const MissionRunSummary fifth = RunMission(mission, out, options);
  EXPECT_EQ(fifth.sites_computed, 2);
  EXPECT_EQ(fifth.legs_reused, 0);
}

// A tiny mission whose one leg has rock tie points to spare: a full Navcam panorama at both
// sites 6 m apart on a rocky field.
MissionOptions TinyRockyMission() {
  MissionOptions o = TinyMission();
  o.scene.rock_abundance_k = 0.4;
  o.scene.rock_min_diameter_m = 0.5;
  o.render.near_radius_m = 8.0;
  o.render.mid_radius_m = 12.0;
  o.traverse.min_leg_m = 3.0;
  o.traverse.max_leg_m = 3.5;
  o.navcam_pairs = 10;
  o.navcam.width = 512;
  o.navcam.height = 512;
  return o;
}

TEST(MissionRun, SecondPassMatchesTheLegsAgainAtTheirOwnVarianceFactor) {
  testing::TempDir dir;
  GenerateMission(TinyRockyMission(), dir.path() / "mission");
  const MissionManifest mission = ReadMissionManifest(dir.path() / "mission");
  const fs::path out = dir.path() / "run";
  MissionRunOptions options;
  options.stereo.min_range_m = 2.0;
  options.detect_craters = false;
  options.traverse_products = false;
  options.guided_passes = 0;
  // The leg's 4 tie points fail RE (2.5 %) at 2 %; accepted here, so that the adjustment shows
  // which covariances it weighs them by.
  options.matching.fault_detection.max_relative_error_percent = 5.0;
  options.rock_variance_pass = false;
  const MissionRunSummary off = RunMission(mission, out, options);
  const nlohmann::json first_ties = off.json["rock_tie_variance"];
  const nlohmann::json first_leg = off.json["legs"][0];
  const int redundancy = first_ties.value("redundancy", 0);
  ASSERT_GT(redundancy, 0) << "the tiny leg needs tie points with redundancy: "
                           << first_ties.dump();
  ASSERT_EQ(first_leg["outcome"], "matched") << first_leg["faults"].dump();
  EXPECT_TRUE(first_ties["applied_factor"].is_null());
  EXPECT_EQ(off.legs_rematched, 0);

  // Less pooled redundancy than asked for: no second pass, nothing matched again.
  options.rock_variance_pass = true;
  options.rock_variance_pass_min_redundancy = redundancy + 1;
  const MissionRunSummary few = RunMission(mission, out, options);
  EXPECT_EQ(few.legs_reused, 1);
  EXPECT_EQ(few.legs_rematched, 0);
  EXPECT_TRUE(few.json["rock_tie_variance"]["applied_factor"].is_null());

  // Enough: the leg is matched again at the first pass's pooled 95 % bound, which stays the
  // first pass's (its figures kept in "first_pass"), and the adjustment weighs the ties as
  // before: by their a-priori covariances.
  options.rock_variance_pass_min_redundancy = redundancy;
  const MissionRunSummary on = RunMission(mission, out, options);
  EXPECT_EQ(on.sites_reused, 2);
  EXPECT_EQ(on.legs_reused, 1);
  EXPECT_EQ(on.legs_rematched, 1);
  const double factor = first_ties["sigma0_squared_upper_95"].get<double>();
  const nlohmann::json& ties = on.json["rock_tie_variance"];
  EXPECT_DOUBLE_EQ(ties["applied_factor"].get<double>(), factor);
  EXPECT_EQ(ties["chi2"], first_ties["chi2"]);
  const nlohmann::json& leg = on.json["legs"][0];
  EXPECT_DOUBLE_EQ(leg["tie_variance_factor"].get<double>(), factor);
  EXPECT_EQ(leg["first_pass"]["outcome"], first_leg["outcome"]);
  EXPECT_EQ(leg["first_pass"]["conformal_chi2"], first_leg["conformal_chi2"]);
  EXPECT_DOUBLE_EQ(leg["first_pass"]["tie_variance_factor"].get<double>(), 1.0);
  const nlohmann::json unit =
      nlohmann::json::parse(ReadText(out / "legs" / "leg_000_001" / "unit.json"));
  EXPECT_EQ(unit["summary"]["first_pass"], leg["first_pass"]);
  // The same tie points (the factor, 1.6 from a redundancy of 4, only widens the outlier test)
  // with their covariances scaled by it: the fit's chi2 shrinks by 1 / factor, the adjustment
  // is the first pass's.
  ASSERT_EQ(leg["outcome"], "matched") << leg["faults"].dump();
  ASSERT_EQ(leg["tie_points"], first_leg["tie_points"]);
  EXPECT_NEAR(leg["conformal_chi2"].get<double>(),
              first_leg["conformal_chi2"].get<double>() / factor,
              1e-9 * first_leg["conformal_chi2"].get<double>());
  EXPECT_NEAR(on.json["adjustment"]["sigma0"].get<double>(),
              off.json["adjustment"]["sigma0"].get<double>(), 1e-9);
  EXPECT_EQ(on.json["adjustment"]["tie_points"], off.json["adjustment"]["tie_points"]);

  // The report shows the factor and the leg's first pass.
  std::ofstream(out / "summary.json") << on.json.dump();
  WriteRunReport(out);
  const std::string html = ReadText(out / "report.html");
  EXPECT_NE(html.find("First pass (a-priori tie covariances): matched"), std::string::npos);
  EXPECT_NE(html.find("variance factor applied by the legs' second pass"), std::string::npos);

  // Resumed: the factor comes out the same, so nothing is matched again.
  const MissionRunSummary again = RunMission(mission, out, options);
  EXPECT_EQ(again.legs_rematched, 0);
  EXPECT_EQ(again.json["rock_tie_variance"], ties);
  EXPECT_EQ(again.json["legs"][0]["first_pass"], leg["first_pass"]);

  // Off again: the leg is matched with the a-priori covariances, as first.
  options.rock_variance_pass = false;
  const MissionRunSummary back = RunMission(mission, out, options);
  EXPECT_EQ(back.legs_rematched, 1);
  EXPECT_FALSE(back.json["legs"][0].contains("first_pass"));
  EXPECT_EQ(back.json["legs"][0]["conformal_chi2"], first_leg["conformal_chi2"]);
  EXPECT_EQ(back.json["rock_tie_variance"], first_ties);
}

TEST(MissionRunOptions, SecondPassFactorIsThePooledUpperBoundWithEnoughRedundancy) {
  MissionRunOptions options;
  PooledVarianceFactor pooled;
  pooled.fits = 3;
  pooled.chi2 = 12.0;
  pooled.redundancy = 40;
  pooled.estimate = 0.3;
  pooled.upper_95 = 0.42;
  ASSERT_TRUE(options.RockVariancePassFactor(pooled).has_value());
  EXPECT_DOUBLE_EQ(*options.RockVariancePassFactor(pooled), 0.42);
  pooled.redundancy = options.rock_variance_pass_min_redundancy - 1;
  EXPECT_FALSE(options.RockVariancePassFactor(pooled).has_value());
  pooled.redundancy = 40;
  pooled.upper_95 = std::nan("");  // Nothing pooled.
  EXPECT_FALSE(options.RockVariancePassFactor(pooled).has_value());
  pooled.upper_95 = 1.6;  // Optimistic covariances (as on the real K10 pair): widened.
  EXPECT_DOUBLE_EQ(*options.RockVariancePassFactor(pooled), 1.6);
  options.rock_variance_pass = false;
  EXPECT_FALSE(options.RockVariancePassFactor(pooled).has_value());
  options.rock_variance_pass = true;
  options.rock_variance_pass_min_redundancy = 0;
  EXPECT_THROW(options.Check(), Error);
}

TEST(MissionRun, PancamPointsReplaceNavcamPointsWhereBothSeeTheGround) {
  // One Navcam and one Pancam pair looking the same way: at the same range a Pancam point is
  // ~4x more precise (Table 1.1: 0.28 against 0.76 mrad/px, 30 against 20 cm baseline; here
  // both 256 px wide with Table 1.1's fields of view), so where both see the ground only the
  // Pancam points stay.
  MissionOptions mission_options = TinyMission();
  mission_options.traverse.site_count = 1;
  mission_options.navcam.field_of_view_deg = 45.0;
  mission_options.pancam_pairs = 1;
  mission_options.pancam.width = 256;
  mission_options.pancam.height = 256;
  mission_options.pancam.field_of_view_deg = 16.8;
  mission_options.pancam_elevation_deg = -20.0;  // Ground 3-7 m away, inside the tiny mesh.
  testing::TempDir dir;
  GenerateMission(mission_options, dir.path() / "mission");
  const MissionManifest mission = ReadMissionManifest(dir.path() / "mission");
  MissionRunOptions options;
  options.stereo.min_range_m = 2.0;
  options.detect_craters = false;
  options.traverse_products = false;

  // Dense enough that most 25 cm cells hold 5 Pancam points. The tiny Pancam's pixels are
  // 1.15 mrad (Navcam's 3.07), so a 2 mrad bound makes it the fine pair.
  options.point_spacing_m = 0.006;
  options.fine_pair_point_spacing_m = 0.005;
  options.fine_pair_max_ifov_mrad = 2.0;

  // Runs the site; its Navcam points, and how many of them lie within 10 cm (horizontally) of a
  // Pancam point, i.e. on ground the Pancam pair saw.
  struct SiteCount {
    nlohmann::json site;
    int navcam = 0, pancam = 0, navcam_on_pancam_ground = 0;
  };
  const auto run_site = [&](const fs::path& out) {
    SiteCount result;
    result.site = RunMission(mission, out, options).json["sites"][0];
    std::map<int, std::string> instrument;  // image_id -> instrument.
    for (const auto& pair : result.site["pairs"]) instrument[pair["image_id"]] = pair["instrument"];
    std::vector<Eigen::Vector2d> navcam, pancam;
    for (const StereoPoint& p : ReadPointCloudPly(out / "sites" / "site_000" / "points.ply").points)
      (instrument.at(p.image_id) == "PANCAM" ? pancam : navcam).push_back(p.position.head<2>());
    result.navcam = static_cast<int>(navcam.size());
    result.pancam = static_cast<int>(pancam.size());
    for (const Eigen::Vector2d& n : navcam) {
      result.navcam_on_pancam_ground +=
          std::any_of(pancam.begin(), pancam.end(),
                      [&](const Eigen::Vector2d& p) { return (p - n).norm() < 0.1; });
    }
    return result;
  };
  options.prefer_precise_pairs = false;
  const SiteCount all = run_site(dir.path() / "all");
  options.prefer_precise_pairs = true;
  const SiteCount kept = run_site(dir.path() / "kept");

  EXPECT_EQ(all.site["coarse_points_dropped"], 0) << all.site.dump();
  for (const auto& pair : all.site["pairs"]) {
    EXPECT_DOUBLE_EQ(pair["point_spacing_m"].get<double>(),
                     pair["instrument"] == "PANCAM" ? 0.005 : 0.006)
        << pair.dump();
  }
  ASSERT_GT(all.pancam, 1000);
  ASSERT_GT(all.navcam_on_pancam_ground, 1000);
  EXPECT_EQ(kept.pancam, all.pancam);  // The precise pair loses nothing.
  EXPECT_EQ(kept.site["coarse_points_dropped"].get<int>(), all.navcam - kept.navcam);
  // On the ground both saw, at most the edges of Pancam's footprint keep Navcam points ...
  EXPECT_LT(kept.navcam_on_pancam_ground, all.navcam_on_pancam_ground / 5);
  // ... elsewhere Navcam keeps its points, but for those in cells Pancam covered in part.
  EXPECT_GT(kept.navcam - kept.navcam_on_pancam_ground,
            0.95 * (all.navcam - all.navcam_on_pancam_ground));
}

TEST(MissionRunOptions, FinePairsKeepTheirPointsCloser) {
  MissionRunOptions options;
  const double navcam_focal_px = 1.0 / 0.76e-3, pancam_focal_px = 1.0 / 0.28e-3;  // Table 1.1.
  EXPECT_EQ(options.PointSpacingFor(navcam_focal_px), options.point_spacing_m);
  EXPECT_EQ(options.PointSpacingFor(1.0 / 2.1e-3), options.point_spacing_m);  // Hazcam.
  EXPECT_EQ(options.PointSpacingFor(pancam_focal_px), options.fine_pair_point_spacing_m);
  EXPECT_LT(options.fine_pair_point_spacing_m, options.point_spacing_m);
  options.fine_pair_max_ifov_mrad = 0.0;  // No pair is fine.
  EXPECT_EQ(options.PointSpacingFor(pancam_focal_px), options.point_spacing_m);
  options.fine_pair_point_spacing_m = 0.0;
  const std::string message = testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("MissionRunOptions.fine_pair_point_spacing_m"), std::string::npos)
      << message;
}

TEST(MissionRunOptions, SiteRotationSigmasChangeTheFingerprint) {
  // A finished site unit is reused only while these figures are unchanged: the orbital match's
  // rotation floor sets the sigmas its registration hands to the adjustment.
  const MissionRunOptions defaults;
  MissionRunOptions floor = defaults, correlation = defaults;
  floor.match.rotation_floor_deg = 0.2;
  correlation.match.rotation_floor_correlation = 0.01;
  EXPECT_NE(floor.ToJson(), defaults.ToJson());
  EXPECT_NE(correlation.ToJson(), defaults.ToJson());
  EXPECT_EQ(MissionRunOptions{}.ToJson(), defaults.ToJson());
}

TEST(MissionRunOptions, RockAmbiguityRuleChangesTheFingerprint) {
  // Legs matched before similar low neighbours counted in the ambiguity test are not reused.
  const MissionRunOptions defaults;
  MissionRunOptions lowest = defaults, difference = defaults;
  lowest.matching.ambiguity_similar_min_height_m = 0.15;
  difference.matching.ambiguity_similar_height_difference = 0.5;
  EXPECT_NE(lowest.ToJson(), defaults.ToJson());
  EXPECT_NE(difference.ToJson(), defaults.ToJson());
  // Nor legs matched before the pattern settled disagreements (2026-12-04).
  MissionRunOptions agree = defaults;
  agree.matching.pattern_settles_disagreement = false;
  EXPECT_NE(agree.ToJson(), defaults.ToJson());
  // Nor legs matched before the consensus translation and the few-point models (2026-12-04).
  MissionRunOptions median = defaults, shapes = defaults;
  median.matching.consensus_translation = false;
  shapes.matching.min_shape_points = 0;
  EXPECT_NE(median.ToJson(), defaults.ToJson());
  EXPECT_NE(shapes.ToJson(), defaults.ToJson());
  // Nor legs whose pairs were compared by their models (before 2026-12-05).
  MissionRunOptions models = defaults;
  models.matching.compare_models = true;
  EXPECT_NE(models.ToJson(), defaults.ToJson());
}

TEST(MissionRunOptions, RockHeightRuleChangesTheFingerprint) {
  // Legs and sites made with a 15 cm rule (before 2026-12-04, or run --rock-min-height 0.15) are
  // not reused with the 12 cm one, nor with another limit for low rocks.
  const MissionRunOptions defaults;
  // Nor legs made with one significant rock per cell (before 2026-12-04) with three.
  MissionRunOptions rule = defaults, models = defaults, low = defaults, cell = defaults,
                    pair = defaults;
  rule.matching.fault_detection.min_peak_to_plane_m = 0.15;
  rule.rocks.model_min_height_m = 0.15;
  low.matching.low_rock_max_peak_sigma_m = 0.6;
  pair.matching.low_pair_max_height_m = 0.15;
  models.rocks.model_min_height_m = 0.10;
  cell.matching.significant_per_cell = 1;
  EXPECT_NE(rule.ToJson(), defaults.ToJson());
  EXPECT_NE(models.ToJson(), defaults.ToJson());
  EXPECT_NE(low.ToJson(), defaults.ToJson());
  EXPECT_NE(pair.ToJson(), defaults.ToJson());
  EXPECT_NE(cell.ToJson(), defaults.ToJson());
}

// Whether changing one rock-matching option from its default changes the run's fingerprint.
bool MatchingChangesTheFingerprint(const std::function<void(RockMatchingOptions*)>& change) {
  MissionRunOptions changed;
  change(&changed.matching);
  return changed.ToJson() != MissionRunOptions{}.ToJson();
}

TEST(MissionRunOptions, RockPatternRulesChangeTheFingerprint) {
  // Legs whose low pairs the pattern could not vouch for (before 2026-12-05) are not reused ...
  EXPECT_TRUE(MatchingChangesTheFingerprint(
      [](RockMatchingOptions* m) { m->pattern_vouch_deviation_m = 0.0; }));
  EXPECT_TRUE(
      MatchingChangesTheFingerprint([](RockMatchingOptions* m) { m->pattern_vouch_votes = 5; }));
  // ... nor those in which a vouched pair's off-pattern neighbours made it ambiguous ...
  EXPECT_TRUE(MatchingChangesTheFingerprint(
      [](RockMatchingOptions* m) { m->pattern_vouch_rules_out_alternatives = false; }));
  // ... nor those matched with the pattern's translation alone (before the pattern's turn).
  EXPECT_TRUE(
      MatchingChangesTheFingerprint([](RockMatchingOptions* m) { m->consensus_turn = false; }));
  EXPECT_TRUE(MatchingChangesTheFingerprint(
      [](RockMatchingOptions* m) { m->consensus_turn_trim_m = 0.4; }));
}

TEST(MissionRunOptions, RocksThatPassTheHeightRuleMustBeModeled) {
  // With the height rule under the model height, rocks between the two would pass the rule and
  // then fail for want of a model: the options are refused, naming the field.
  MissionRunOptions options;
  EXPECT_LE(options.rocks.model_min_height_m, options.matching.fault_detection.min_peak_to_plane_m);
  options.matching.fault_detection.min_peak_to_plane_m = 0.10;
  const std::string message = testing::ErrorMessageOf([&] { options.Check(); });
  EXPECT_NE(message.find("RockExtractionOptions.model_min_height_m"), std::string::npos) << message;
}

TEST(MissionRun, GuidedPriorFollowsTheAdjustedPose) {
  // Telemetry: level, north-up at (10, 20) m; the adjustment moves the site 1 m north, 0.5 m
  // west and turns it 5 degrees from north towards east (about z, down): clockwise on the map.
  const Rigid3d telemetry(Eigen::Quaterniond::Identity(), Eigen::Vector3d(10.0, 20.0, 0.0));
  const double turn = 5.0 * std::numbers::pi / 180.0;
  const Rigid3d adjusted(Eigen::Quaterniond(Eigen::AngleAxisd(turn, Eigen::Vector3d::UnitZ())),
                         Eigen::Vector3d(11.0, 19.5, 0.1));
  Matrix6d covariance = Matrix6d::Identity() * 1e-4;
  covariance.block<2, 2>(3, 3) << 0.64, 0.1, 0.1, 0.09;  // North, east [m^2].
  const GuidedPrior prior = GuidedPriorFromPoses(telemetry, adjusted, covariance, 0.5);
  EXPECT_NEAR(prior.shift_en_m.x(), -0.5, 1e-12);
  EXPECT_NEAR(prior.shift_en_m.y(), 1.0, 1e-12);
  EXPECT_NEAR(prior.rotation_rad, -turn, 1e-12);
  // The largest eigenvalue of the horizontal block: (0.73 + sqrt(0.55^2 + 0.2^2)) / 2.
  EXPECT_NEAR(prior.sigma_m, std::sqrt((0.73 + std::hypot(0.55, 0.2)) / 2.0), 1e-12);
  // A well-known site gets the floor.
  covariance.block<2, 2>(3, 3) = Eigen::Matrix2d::Identity() * 0.01;
  EXPECT_DOUBLE_EQ(GuidedPriorFromPoses(telemetry, adjusted, covariance, 0.5).sigma_m, 0.5);
  covariance(3, 3) = std::nan("");
  EXPECT_THROW(GuidedPriorFromPoses(telemetry, adjusted, covariance, 0.5), Error);
}

// The public jobs (mission_jobs.h), called on a finished run's folder, give the records the run
// made of its units.
TEST(MissionJobs, GiveTheRunsRecords) {
  testing::TempDir dir;
  const MissionManifest mission = TinyMissionIn(dir.path());
  const fs::path out = dir.path() / "run";
  MissionRunOptions options = TinyRunOptions();
  options.traverse_products = false;
  const RunSummary run = RunMission(mission, out, options).record;
  const mission_run::MissionRunContext context(mission, options, out);

  const mission_run::SiteUnitResult site = mission_run::RegisterSite(context, 1);
  EXPECT_EQ(site.points, run.sites[1].points);
  EXPECT_EQ(site.registration.ToJson().dump(), run.sites[1].registration.ToJson().dump());
  const mission_run::LegUnitResult leg = mission_run::MatchLeg(context, 0, options.matching);
  EXPECT_EQ(leg.match.outcome, run.legs[0].first_pass.value_or(run.legs[0].match).outcome);
  EXPECT_EQ(leg.rocks_a.rocks, run.legs[0].rocks_a.rocks);
  EXPECT_TRUE(leg.match.seconds.has_value());
  const mission_run::CratersUnitResult craters = mission_run::DetectOrbitalCraters(context);
  ASSERT_TRUE(run.craters.has_value());
  EXPECT_EQ(craters.craters, run.craters->craters);
  EXPECT_EQ(craters.score, run.craters->score);
  // The leg's tie points as the legs' test left them (rock_ties/ when it changed them).
  fs::path ties = out / "adjustment" / "rock_ties" / "leg_000_001.json";
  if (!fs::exists(ties)) ties = out / "legs" / "leg_000_001" / "tie_points.json";
  const mission_run::AdjustmentResult adjusted =
      mission_run::AdjustTraverse({out / "adjustment",
                                   {out / "sites" / "site_000" / "control_points.json",
                                    out / "sites" / "site_001" / "control_points.json"},
                                   {ties},
                                   {}});
  EXPECT_EQ(adjusted.sites, 2);
  EXPECT_TRUE(fs::exists(out / "adjustment" / "adjustment.json"));
}

TEST(MissionRun, ReportNeedsARunFolder) {
  testing::TempDir dir;
  const std::string message = testing::ErrorMessageOf([&] { WriteRunReport(dir.path()); });
  EXPECT_NE(message.find("no summary.json"), std::string::npos) << message;
}

}  // namespace
}  // namespace areomap
