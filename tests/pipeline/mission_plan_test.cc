// The mission run as a plan (mission_plan.h): its stages and dependencies, its units run one at a
// time giving the local run's figures, and the refusals (a unit before what it needs, a plan
// whose options changed, a unit the plan lacks).
#include "areomap/pipeline/mission_plan.h"

#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include <unistd.h>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/pipeline/executors.h"
#include "areomap/samples/mission.h"
#include "test_support.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

MissionOptions ThreeSites() {
  MissionOptions o = MissionOptions::Preset("demo");
  o.scene.half_extent_m = 40.0;
  o.scene.crater_count = 1;
  o.traverse.site_count = 3;
  o.traverse.min_leg_m = 6.0;
  o.traverse.max_leg_m = 8.0;
  o.navcam_pairs = 1;
  o.navcam.width = 256;
  o.navcam.height = 256;
  o.pancam_pairs = 0;
  o.render.near_radius_m = 2.0;
  o.render.mid_radius_m = 8.0;
  return o;
}

MissionRunOptions Options() {
  MissionRunOptions options;
  options.stereo.min_range_m = 2.0;
  options.traverse_products = false;
  return options;
}

// summary.json without what differs between two ways of running the same units: times, which
// units this invocation computed, the mission path.
json Figures(json summary) {
  std::function<void(json&)> strip = [&](json& v) {
    if (v.is_object()) {
      for (auto it = v.begin(); it != v.end();) {
        if (it.key().ends_with("seconds")) {
          it = v.erase(it);
        } else {
          strip(*it);
          ++it;
        }
      }
    } else if (v.is_array()) {
      for (json& x : v) strip(x);
    }
  };
  summary.erase("units");
  summary.erase("mission");
  strip(summary);
  return summary;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

class MissionPlanTest : public ::testing::Test {
 protected:
  // One mission for the suite (generating it is most of a test's time).
  static void SetUpTestSuite() {
    root_ = fs::temp_directory_path() / ("areomap-MissionPlan-" + std::to_string(::getpid()));
    fs::remove_all(root_);
    GenerateMission(ThreeSites(), root_ / "mission");
  }
  static void TearDownTestSuite() { fs::remove_all(root_); }
  static fs::path Mission() { return root_ / "mission"; }
  void SetUp() override { dir_ = std::make_unique<testing::TempDir>(); }
  static fs::path root_;
  std::unique_ptr<testing::TempDir> dir_;
};
fs::path MissionPlanTest::root_;

TEST_F(MissionPlanTest, StagesFollowTheRunsDependencies) {
  const MissionManifest mission = ReadMissionManifest(Mission());
  const WorkPlan plan = PlanMission(mission, dir_->path() / "out", Options(), {"--no-products"});
  ASSERT_EQ(plan.stages.size(), 5u);
  EXPECT_EQ(plan.stages[0].name, "sites");
  EXPECT_EQ(plan.stages[0].units.size(), 3u);
  const PlannedUnit& leg = plan.Unit("leg_001_002");
  EXPECT_EQ(leg.after, (std::vector<std::string>{"site_001", "site_002"}));
  EXPECT_EQ(leg.folder, "legs/leg_001_002");
  EXPECT_EQ(plan.Unit("leg_000_001_pass2").after,
            (std::vector<std::string>{"leg_000_001", "leg_001_002"}));
  EXPECT_EQ(plan.stages[3].name, "craters");
  const PlannedUnit& finish = plan.Unit("finish");
  EXPECT_EQ(finish.after.size(), 3u + 2u + 1u);  // Sites, second passes, craters.
  EXPECT_EQ(plan.arguments, std::vector<std::string>{"--no-products"});
  MissionRunOptions no_craters = Options();
  no_craters.detect_craters = false;
  const WorkPlan without = PlanMission(mission, dir_->path() / "out", no_craters, {});
  EXPECT_THROW(without.Stage("craters"), Error);
  EXPECT_NE(without.fingerprint, plan.fingerprint);
}

TEST_F(MissionPlanTest, UnitsOneAtATimeGiveTheLocalRun) {
  const fs::path local = dir_->path() / "local";
  const fs::path planned = dir_->path() / "planned";
  const MissionRunSummary expected = RunMissionFolder(Mission(), local, Options());
  const WorkPlan plan = PlanMissionFolder(Mission(), planned, Options(), {});
  EXPECT_EQ(ReadWorkPlan(planned).ToJson(), plan.ToJson());
  // A leg before its sites: refused with error.txt naming the missing site unit; the next
  // named unit still runs.
  std::vector<UnitRunRecord> records =
      RunMissionPlanUnits(planned, plan, Options(), {"leg_000_001", "site_000"}, {});
  ASSERT_EQ(records.size(), 2u);
  EXPECT_EQ(records[0].outcome, UnitOutcome::kFailed);
  EXPECT_NE(records[0].error.find("site unit site_000"), std::string::npos) << records[0].error;
  EXPECT_NE(ReadText(planned / "legs" / "leg_000_001" / "error.txt").find("site_000"),
            std::string::npos);
  EXPECT_EQ(records[1].outcome, UnitOutcome::kComputed);
  std::vector<UnitStatus> status = ReadPlanStatus(planned, plan);
  EXPECT_EQ(status[0].state, UnitState::kDone);     // site_000
  EXPECT_EQ(status[1].state, UnitState::kPending);  // site_001
  EXPECT_EQ(status[3].state, UnitState::kFailed);   // leg_000_001
  // Every unit in plan order; site_000 again is reused.
  for (const PlannedStage& stage : plan.stages) {
    for (const PlannedUnit& unit : stage.units) {
      records = RunMissionPlanUnits(planned, plan, Options(), {unit.id}, {});
      ASSERT_EQ(records.size(), 1u);
      EXPECT_NE(records[0].outcome, UnitOutcome::kFailed) << unit.id << ": " << records[0].error;
      if (unit.id == "site_000") {
        EXPECT_EQ(records[0].outcome, UnitOutcome::kReused);
      }
    }
  }
  EXPECT_FALSE(fs::exists(planned / "legs" / "leg_000_001" / "error.txt"));
  for (const UnitStatus& s : ReadPlanStatus(planned, plan)) {
    EXPECT_EQ(s.state, UnitState::kDone) << s.id;
  }
  const json summary = json::parse(ReadText(planned / "summary.json"));
  EXPECT_EQ(Figures(summary), Figures(expected.json));
  EXPECT_EQ(summary["units"]["sites_reused"], 3);
  EXPECT_TRUE(fs::exists(planned / "report.html"));
  EXPECT_EQ(ReadText(planned / "sites" / "site_002" / "points.ply"),
            ReadText(local / "sites" / "site_002" / "points.ply"));
  // Done units are not run again; `finish` is not either.
  records = RunMissionPlanUnits(planned, plan, Options(), {"site_001", "finish"}, {});
  EXPECT_EQ(records[0].outcome, UnitOutcome::kReused);
  EXPECT_EQ(records[1].outcome, UnitOutcome::kReused);
  // The same plan asked for again (a second executor) is the one in place.
  EXPECT_EQ(PlanMissionFolder(Mission(), planned, Options(), {}).ToJson(), plan.ToJson());
}

TEST_F(MissionPlanTest, RefusesAPlanWhoseOptionsChangedAndUnitsItLacks) {
  const fs::path out = dir_->path() / "refusals";
  const WorkPlan plan = PlanMissionFolder(Mission(), out, Options(), {});
  MissionRunOptions other = Options();
  other.dtm.posting_m = 0.2;
  try {
    RunMissionPlanUnits(out, plan, other, {"site_000"}, {});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("changed since this plan was written"), std::string::npos)
        << e.what();
  }
  try {
    RunMissionPlanUnits(out, plan, Options(), {"site_000", "site_007"}, {});
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no unit \"site_007\""), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(out / "sites" / "site_000" / "unit.json"));  // Nothing ran.
}

}  // namespace
}  // namespace areomap
