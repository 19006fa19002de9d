#include "areomap/landmarks/leg_consistency.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "mission_units.h"
#include "test_support.h"

namespace areomap {
namespace {

// One leg: site b 12 m ahead of site a, turned by 3 degrees; `count` rocks 3-18 m ahead of a,
// their covariances eq. 4.2's (Navcam, sigma_p 0.5 px) at each site, and their measured positions
// off by errors drawn at `noise_scale` x those sigmas (0.5: covariances 4x pessimistic in
// variance, as on the generated missions, docs/rocks.md).
std::vector<TiePoint> Leg(std::mt19937* rng, int count, double noise_scale) {
  const LocalizationCamera camera;
  const double turn = 3.0 * std::numbers::pi / 180.0;
  Eigen::Matrix2d b_to_a;
  b_to_a << std::cos(turn), -std::sin(turn), std::sin(turn), std::cos(turn);
  const Eigen::Vector2d b_in_a(12.0, -1.5);
  std::uniform_real_distribution<double> along(3.0, 18.0), across(-6.0, 6.0);
  std::normal_distribution<double> gauss(0.0, noise_scale);
  std::vector<TiePoint> ties;
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector2d p(along(*rng), across(*rng));
    const Eigen::Matrix2d cov_a = camera.Covariance(p, Eigen::Vector2d::Zero());
    const Eigen::Matrix2d cov_b =
        b_to_a.transpose() * camera.Covariance(p, b_in_a) * b_to_a;  // in b's frame
    const Eigen::Vector2d exact_b = b_to_a.transpose() * (p - b_in_a);
    const Eigen::Vector2d n_a(gauss(*rng), gauss(*rng)), n_b(gauss(*rng), gauss(*rng));
    TiePoint t;
    t.id = "r";
    t.id += std::to_string(k);
    t.site_a = 0;
    t.site_b = 1;
    t.position_in_a << p + cov_a.llt().matrixL() * n_a, 0.0;
    t.position_in_b << exact_b + cov_b.llt().matrixL() * n_b, 0.0;
    t.covariance_in_a = Eigen::Matrix3d::Identity() * 0.01;
    t.covariance_in_a.topLeftCorner<2, 2>() = cov_a;
    t.covariance_in_b = Eigen::Matrix3d::Identity() * 0.01;
    t.covariance_in_b.topLeftCorner<2, 2>() = cov_b;
    ties.push_back(t);
  }
  return ties;
}

std::vector<std::vector<TiePoint>> Traverse(std::mt19937* rng, int legs, double noise_scale) {
  std::uniform_int_distribution<int> count(4, 10);
  std::vector<std::vector<TiePoint>> out;
  for (int i = 0; i < legs; ++i) out.push_back(Leg(rng, count(*rng), noise_scale));
  return out;
}

TEST(LegConsistency, FalseAlarmRateIsAlphaWhateverTheCommonFactor) {
  // Legs without outliers, their covariances right (1.0) or 4x pessimistic (0.5): the test
  // compares each leg with the others, so the common factor does not matter and about alpha of
  // the legs fail (2400 legs at alpha 0.01: 24 expected, sd ~5; the rounds that leave failing
  // legs out of the reference add some: 33 and 34 measured).
  LegConsistencyOptions options;
  options.alpha = 0.01;
  for (const double noise_scale : {1.0, 0.5}) {
    std::mt19937 rng(3);
    int legs = 0, failed = 0;
    for (int run = 0; run < 200; ++run) {
      const std::vector<std::vector<TiePoint>> traverse = Traverse(&rng, 12, noise_scale);
      for (const LegConsistency& v : TestLegConsistency(traverse, options)) {
        ASSERT_TRUE(v.tested);
        ++legs;
        failed += v.first_f_statistic > v.f_threshold ? 1 : 0;
      }
    }
    EXPECT_EQ(legs, 2400);
    EXPECT_GE(failed, 10) << noise_scale;
    EXPECT_LE(failed, 45) << noise_scale;
  }
}

TEST(LegConsistency, DropsAWrongTiePointThatItsOwnLegsTestMisses) {
  // Covariances 4x pessimistic in variance; in one leg of twelve a tie point joins the wrong
  // rock, off across the line of sight by 3 sigmas of its discrepancy as the covariances state
  // it (6 true sigmas). Against the leg's own covariances its leave-one-out chi-square stays
  // under 13.8 in most draws (what MatchSitePair tests); against the other legs' precision it is
  // the one dropped, and the leg keeps the rest.
  std::mt19937 rng(5);
  int own_test_missed = 0, dropped_it = 0, dropped_more = 0, other_legs_changed = 0;
  const int runs = 100;
  for (int run = 0; run < runs; ++run) {
    std::vector<std::vector<TiePoint>> traverse = Traverse(&rng, 12, 0.5);
    std::vector<TiePoint>& leg = traverse[4];
    leg = Leg(&rng, 6, 0.5);
    leg[1].position_in_a.y() +=
        3.0 * std::sqrt(leg[1].covariance_in_a(1, 1) + leg[1].covariance_in_b(1, 1));
    std::vector<PlanarTiePoint> planar;
    for (const TiePoint& t : leg) planar.push_back(PlanarTie(t));
    own_test_missed += LeaveOneOutChi2(planar)[1] <= 13.8 ? 1 : 0;
    const std::vector<LegConsistency> v = TestLegConsistency(traverse);
    ASSERT_TRUE(v[4].tested);
    EXPECT_FALSE(v[4].excluded);
    dropped_it += !v[4].dropped.empty() && v[4].dropped.front() == 1 ? 1 : 0;
    dropped_more += v[4].dropped.size() > 1 ? 1 : 0;
    for (size_t i = 0; i < v.size(); ++i) {
      if (i != 4) other_legs_changed += v[i].dropped.empty() && !v[i].excluded ? 0 : 1;
    }
  }
  // Measured (seed 5): own test missed 55 of 100, this test dropped it in 76 (its power at 6
  // true sigmas with the leg's redundancy of 8), something more in 2, another leg in 1.
  EXPECT_GE(own_test_missed, 40);
  EXPECT_GE(dropped_it, 65);
  EXPECT_LE(dropped_more, 5);
  EXPECT_LE(other_legs_changed, 3);  // alpha 0.001 x 1100 legs
}

TEST(LegConsistency, ExcludesALegWithNoTiePointToSpare) {
  // Three tie points, one of them 1 m off across the line of sight: the leg fails and has none
  // to drop.
  std::mt19937 rng(9);
  std::vector<std::vector<TiePoint>> traverse = Traverse(&rng, 8, 0.5);
  traverse[2] = Leg(&rng, 3, 0.5);
  traverse[2][0].position_in_a.y() += 1.0;
  const std::vector<LegConsistency> v = TestLegConsistency(traverse);
  EXPECT_TRUE(v[2].tested);
  EXPECT_TRUE(v[2].excluded);
  EXPECT_TRUE(v[2].dropped.empty());
  EXPECT_GT(v[2].f_statistic, v[2].f_threshold);
}

TEST(LegConsistency, LegsWithoutRedundancyOrReferenceAreNotTested) {
  std::mt19937 rng(13);
  // An excluded leg (no tie points) and a two-point leg have no fit; the one leg with a fit then
  // has no reference.
  std::vector<std::vector<TiePoint>> traverse = {{}, Leg(&rng, 2, 0.5), Leg(&rng, 6, 0.5)};
  for (const LegConsistency& v : TestLegConsistency(traverse)) {
    EXPECT_FALSE(v.tested);
    EXPECT_FALSE(v.excluded);
    EXPECT_TRUE(v.dropped.empty());
    EXPECT_EQ(v.ToJson().dump(), R"({"tested":false})");
  }
  EXPECT_TRUE(TestLegConsistency({}).empty());
}

TEST(LegConsistency, BadOptionsNameTheField) {
  LegConsistencyOptions options;
  options.alpha = 1.0;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              TestLegConsistency({}, options);
            }).find("LegConsistencyOptions.alpha"),
            std::string::npos);
  options = {};
  options.min_tie_points = 1;
  EXPECT_NE(testing::ErrorMessageOf([&] {
              options.Check();
            }).find("LegConsistencyOptions.min_tie_points"),
            std::string::npos);
}

// A run's legs gathered (mission_units.h TestLegsAgainstEachOther): each leg's tie_points.json
// and summary as RunLegUnit leaves them.
struct GatheredLegs {
  MissionManifest mission;
  MissionRunOptions options;
  std::vector<mission_run::LegUnitResult> summaries;
};

GatheredLegs Gather(const std::filesystem::path& out,
                    const std::vector<std::vector<TiePoint>>& traverse) {
  GatheredLegs g;
  g.mission.root = out;
  for (size_t i = 0; i <= traverse.size(); ++i) {
    g.mission.sites.push_back(MissionSite{static_cast<int>(i), {}});
    const double k = static_cast<double>(i);  // each leg 12 m north, 1.5 m west, as Leg() has it
    g.mission.telemetry.push_back({static_cast<int>(i), Eigen::Vector3d(12.0 * k, -1.5 * k, 0.0)});
  }
  const mission_run::RunContext run(g.mission, g.options, out);
  for (size_t i = 0; i < traverse.size(); ++i) {
    const std::filesystem::path dir =
        mission_run::LegDir(run, static_cast<int>(i), static_cast<int>(i) + 1);
    std::filesystem::create_directories(dir);
    WriteFileAtomically(dir / "tie_points.json",
                        nlohmann::json{{"tie_points", TiePointsToJson(traverse[i])}}.dump());
    mission_run::LegUnitResult leg;
    leg.site_a = static_cast<int>(i);
    leg.site_b = static_cast<int>(i) + 1;
    leg.match.outcome = "matched";
    leg.match.tie_points = static_cast<int64_t>(traverse[i].size());
    leg.match.relative_error_percent = 1.0;
    leg.prior.emplace();
    leg.prior->a_from_b_translation_m = std::array<double, 3>{12.0, -1.5, 0.0};
    g.summaries.push_back(leg);
  }
  return g;
}

TEST(LegConsistency, ARunReadsTheTiePointsTheLegsTestLeft) {
  testing::TempDir dir;
  std::mt19937 rng(5);
  std::vector<std::vector<TiePoint>> traverse = Traverse(&rng, 8, 0.5);
  traverse[2] = Leg(&rng, 6, 0.5);  // one tie point 1.5 m off across: dropped
  traverse[2][3].position_in_a.y() += 1.5;
  traverse[5] = Leg(&rng, 3, 0.5);  // three, one 1.5 m off: excluded
  traverse[5][0].position_in_a.y() += 1.5;
  GatheredLegs g = Gather(dir.path(), traverse);
  // A leg unit from before legs recorded their prior pose: RE falls back to telemetry.
  GatheredLegs without_prior = Gather(dir.path() / "without_prior", traverse);
  without_prior.summaries[2].prior.reset();
  const mission_run::RunContext run(g.mission, g.options, dir.path());
  const std::filesystem::path ties_dir = dir.path() / "adjustment" / "rock_ties";
  const std::vector<std::filesystem::path> files =
      mission_run::TestLegsAgainstEachOther(run, g.summaries, ties_dir);
  ASSERT_EQ(files.size(), 8u);
  for (size_t i = 0; i < 8; ++i) {
    const mission_run::LegUnitResult& leg = g.summaries[i];
    ASSERT_TRUE(leg.leg_test && leg.leg_test->tested) << i;
    const std::vector<FaultCheck>& rules = leg.faults.checks;
    ASSERT_GE(rules.size(), 1u);
    EXPECT_EQ(rules[0].rule, "leg's variance factor / other legs' (F test)");
    if (i == 2 || i == 5) continue;
    EXPECT_EQ(files[i], mission_run::LegDir(run, static_cast<int>(i), static_cast<int>(i) + 1) /
                            "tie_points.json");
    EXPECT_EQ(leg.match.outcome, "matched");
    EXPECT_TRUE(leg.leg_test_dropped_ids.empty());
  }
  // The dropped tie point is gone from what the adjustment reads; RE re-evaluated without it.
  EXPECT_EQ(files[2], ties_dir / "leg_002_003.json");
  const std::vector<TiePoint> kept = ReadTiePoints(files[2]);
  ASSERT_EQ(kept.size(), 5u);
  for (const TiePoint& t : kept) EXPECT_NE(t.id, "r3");
  EXPECT_EQ(g.summaries[2].leg_test_dropped_ids, std::vector<std::string>{"r3"});
  EXPECT_EQ(g.summaries[2].match.outcome, "matched");
  EXPECT_EQ(g.summaries[2].match.tie_points, 5);
  ASSERT_TRUE(g.summaries[2].match.relative_error_percent);
  EXPECT_NE(*g.summaries[2].match.relative_error_percent, 1.0);
  const mission_run::RunContext run_without(without_prior.mission, without_prior.options,
                                            dir.path() / "without_prior");
  mission_run::TestLegsAgainstEachOther(run_without, without_prior.summaries,
                                        dir.path() / "without_prior" / "rock_ties");
  EXPECT_NEAR(without_prior.summaries[2].match.relative_error_percent.value_or(-1.0),
              *g.summaries[2].match.relative_error_percent, 1e-9);
  // The rule failed as first tested, passes without the dropped one; RE after the test passes.
  const std::vector<FaultCheck>& rules2 = g.summaries[2].faults.checks;
  ASSERT_EQ(rules2.size(), 3u);
  EXPECT_EQ(rules2[0].verdict, FaultVerdict::kFail);
  EXPECT_FALSE(rules2[0].excludes_pair);
  EXPECT_EQ(rules2[1].verdict, FaultVerdict::kPass);
  EXPECT_EQ(rules2[2].verdict, FaultVerdict::kPass);
  // The excluded leg: no tie point for the adjustment, and its outcome says so.
  EXPECT_TRUE(ReadTiePoints(files[5]).empty());
  EXPECT_EQ(g.summaries[5].match.outcome, "excluded by fault detection");
  EXPECT_EQ(g.summaries[5].faults.outcome, PairOutcome::kExcludedByFaultDetection);
  EXPECT_EQ(g.summaries[5].match.tie_points, 0);
  EXPECT_TRUE(g.summaries[5].leg_test->excluded);

  // Switched off: every leg's own file, summaries untouched.
  GatheredLegs off = Gather(dir.path() / "off", traverse);
  off.options.leg_test = false;
  const std::vector<mission_run::LegUnitResult> before = off.summaries;
  const mission_run::RunContext run_off(off.mission, off.options, dir.path() / "off");
  const std::vector<std::filesystem::path> own =
      mission_run::TestLegsAgainstEachOther(run_off, off.summaries, ties_dir);
  EXPECT_EQ(own[2], mission_run::LegDir(run_off, 2, 3) / "tie_points.json");
  EXPECT_EQ(off.summaries, before);
  // The first call's files are not this run's: removed, one per leg; the folder itself (which
  // may hold a user's files) stays.
  for (const auto& entry : std::filesystem::directory_iterator(ties_dir)) {
    ADD_FAILURE() << "left behind: " << entry.path();
  }
}

}  // namespace
}  // namespace areomap
