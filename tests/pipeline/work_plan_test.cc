// The plan file (work_plan.h): its JSON round trip, and plans that are not ours refused naming
// the file and the field.
#include "areomap/pipeline/work_plan.h"

#include <fstream>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "test_support.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

WorkPlan SmallPlan() {
  WorkPlan plan;
  plan.job = "run";
  plan.inputs = {"/data/mission"};
  plan.arguments = {"--posting", "0.2", "--no-craters"};
  plan.fingerprint = "abc";
  plan.stages = {{"sites", {}, {{"site_000", "sites/site_000", {}, "site 0"}}},
                 {"legs", {"sites"}, {{"leg_000_001", "legs/leg_000_001", {"site_000"}, ""}}}};
  return plan;
}

std::string ErrorOf(const nlohmann::json& json) {
  try {
    WorkPlan::FromJson(json, "DIR/plan.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(WorkPlan, RoundTripsThroughItsFile) {
  testing::TempDir dir;
  const WorkPlan plan = SmallPlan();
  WriteWorkPlan(dir.path(), plan);
  const WorkPlan read = ReadWorkPlan(dir.path());
  EXPECT_EQ(read.ToJson(), plan.ToJson());
  EXPECT_EQ(read.UnitCount(), 2u);
  const PlannedStage* stage = nullptr;
  EXPECT_EQ(read.Unit("leg_000_001", &stage).after, std::vector<std::string>{"site_000"});
  EXPECT_EQ(stage->name, "legs");
  EXPECT_EQ(ErrorFile(dir.path(), read.Unit("site_000")),
            dir.path() / "sites" / "site_000" / "error.txt");
}

TEST(WorkPlan, RefusesWhatIsNotAPlanNamingTheField) {
  nlohmann::json json = SmallPlan().ToJson();
  EXPECT_NE(ErrorOf({{"format", "other"}}).find("not an areomap plan"), std::string::npos);
  json["version"] = 2;
  EXPECT_NE(ErrorOf(json).find("plan version 2 is not supported"), std::string::npos);
  json = SmallPlan().ToJson();
  json.erase("fingerprint");
  EXPECT_NE(ErrorOf(json).find("DIR/plan.json: field \"fingerprint\""), std::string::npos);
  json = SmallPlan().ToJson();
  json["stages"][1]["units"][0]["id"] = "site_000";
  EXPECT_NE(ErrorOf(json).find("\"site_000\" appears twice"), std::string::npos);
  json = SmallPlan().ToJson();
  json["stages"][0]["units"][0]["folder"] = "../elsewhere";
  EXPECT_NE(ErrorOf(json).find("must lie inside"), std::string::npos);
  json = SmallPlan().ToJson();
  json["stages"][0]["units"][0]["id"] = "Site 0";
  EXPECT_NE(ErrorOf(json).find("[a-z0-9_]+"), std::string::npos);
}

TEST(WorkPlan, MissingPlanSaysHowToMakeOne) {
  testing::TempDir dir;
  try {
    ReadWorkPlan(dir.path());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--plan"), std::string::npos) << e.what();
  }
  EXPECT_THROW(SmallPlan().Unit("site_009"), Error);
  EXPECT_THROW(SmallPlan().Stage("products"), Error);
}

TEST(WorkPlan, DoneFilesCarryTheFingerprint) {
  testing::TempDir dir;
  EXPECT_FALSE(DoneFileMatches(dir.path(), "finish", "abc"));
  WriteDoneFile(dir.path(), "finish", "abc");
  EXPECT_TRUE(DoneFileMatches(dir.path(), "finish", "abc"));
  EXPECT_FALSE(DoneFileMatches(dir.path(), "finish", "abd"));
}

}  // namespace
}  // namespace areomap
