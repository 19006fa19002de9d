// Claims on plan units (unit_claim.h): exclusive while held, released on destruction, taken over
// when the holder died (this host: at once; elsewhere: when untouched for stale_after_s), one
// taker among many, and a failed unit's error file.
#include "areomap/pipeline/unit_claim.h"

#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "areomap/map/error.h"
#include "areomap/pipeline/work_plan.h"
#include "test_support.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

UnitClaimOptions Fast() {
  UnitClaimOptions o;
  o.heartbeat_s = 0.05;
  o.stale_after_s = 1.0;
  o.poll_s = 0.02;
  return o;
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A claim file as a holder on another host wrote it, last touched `age_s` ago.
void WriteForeignClaim(const fs::path& file, double age_s) {
  fs::create_directories(file.parent_path());
  std::ofstream(file) << R"({"host":"node-elsewhere","pid":12345,"process_start":1,"token":"t"})";
  const auto when =
      fs::file_time_type::clock::now() - std::chrono::duration_cast<fs::file_time_type::duration>(
                                             std::chrono::duration<double>(age_s));
  fs::last_write_time(file, when);
}

TEST(UnitClaim, IsExclusiveWhileHeldAndFreeAfter) {
  testing::TempDir dir;
  const fs::path file = dir.path() / "units" / "a.claim";
  {
    const auto first = UnitClaim::TryClaim(file, Fast());
    ASSERT_NE(first, nullptr);
    EXPECT_TRUE(fs::exists(file));
    EXPECT_EQ(UnitClaim::TryClaim(file, Fast()), nullptr);  // This live process holds it.
    const std::optional<ClaimHolder> holder = ReadClaimHolder(file);
    ASSERT_TRUE(holder);
    EXPECT_EQ(holder->pid, ::getpid());
    EXPECT_EQ(holder->token, first->token());
    EXPECT_FALSE(IsStale(*holder, Fast()));
  }
  EXPECT_FALSE(fs::exists(file));
  EXPECT_NE(UnitClaim::TryClaim(file, Fast()), nullptr);
}

TEST(UnitClaim, HeartbeatKeepsALongUnitFresh) {
  testing::TempDir dir;
  const fs::path file = dir.path() / "a.claim";
  const auto claim = UnitClaim::TryClaim(file, Fast());
  ASSERT_NE(claim, nullptr);
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // Beyond stale_after_s.
  const std::optional<ClaimHolder> holder = ReadClaimHolder(file);
  ASSERT_TRUE(holder);
  EXPECT_LT(holder->age_s, 0.5);
  EXPECT_FALSE(IsStale(*holder, Fast()));
}

TEST(UnitClaim, ADeadHolderOnThisHostIsTakenOverAtOnce) {
  testing::TempDir dir;
  const fs::path file = dir.path() / "a.claim";
  UnitClaimOptions slow = Fast();
  slow.stale_after_s = 3600.0;  // Only the dead pid can make it stale.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const auto claim = UnitClaim::TryClaim(file, slow);
    std::_Exit(claim ? 0 : 1);  // Ends without releasing: as after SIGKILL.
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_EQ(WEXITSTATUS(status), 0);
  ASSERT_TRUE(fs::exists(file));
  const std::optional<ClaimHolder> holder = ReadClaimHolder(file);
  ASSERT_TRUE(holder);
  EXPECT_EQ(holder->pid, child);
  EXPECT_TRUE(IsStale(*holder, slow));
  const auto taken = UnitClaim::TryClaim(file, slow);
  ASSERT_NE(taken, nullptr);
  EXPECT_EQ(ReadClaimHolder(file)->token, taken->token());
}

TEST(UnitClaim, AnotherHostsClaimIsStaleOnlyWhenUntouchedLongEnough) {
  testing::TempDir dir;
  const fs::path file = dir.path() / "a.claim";
  WriteForeignClaim(file, 0.2);
  EXPECT_EQ(UnitClaim::TryClaim(file, Fast()), nullptr);  // Fresh: its holder may be alive.
  EXPECT_EQ(ReadClaimHolder(file)->host, "node-elsewhere");
  WriteForeignClaim(file, 5.0);
  const auto taken = UnitClaim::TryClaim(file, Fast());
  ASSERT_NE(taken, nullptr);
  EXPECT_EQ(ReadClaimHolder(file)->token, taken->token());
}

TEST(UnitClaim, OneTakerAmongManyForAStaleClaim) {
  testing::TempDir dir;
  for (int round = 0; round < 20; ++round) {
    const fs::path file = dir.path() / ("stale" + std::to_string(round) + ".claim");
    WriteForeignClaim(file, 10.0);
    std::atomic<int> winners = 0;
    std::vector<std::unique_ptr<UnitClaim>> claims(8);
    std::vector<std::thread> threads;
    for (size_t t = 0; t < claims.size(); ++t) {
      threads.emplace_back([&, t] {
        claims[t] = UnitClaim::TryClaim(file, Fast());
        if (claims[t]) ++winners;
      });
    }
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(winners.load(), 1) << "round " << round;
  }
}

TEST(UnitClaim, FailedUnitLeavesItsErrorAndASuccessRemovesIt) {
  testing::TempDir dir;
  const fs::path claim = dir.path() / ".units" / "u.claim";
  const fs::path error = dir.path() / "u" / "error.txt";
  bool done = false;
  std::string message;
  EXPECT_EQ(RunClaimedUnit(
                claim, error, "u", [&] { return done; },
                [] { throw Error("points.ply: cannot be written"); }, Fast(), true, &message),
            UnitOutcome::kFailed);
  EXPECT_EQ(message, "points.ply: cannot be written");
  const std::string text = ReadText(error);
  EXPECT_NE(text.find("unit: u\n"), std::string::npos) << text;
  EXPECT_NE(text.find("error: points.ply: cannot be written"), std::string::npos) << text;
  EXPECT_FALSE(fs::exists(claim));  // Released.
  EXPECT_EQ(
      RunClaimedUnit(
          claim, error, "u", [&] { return done; }, [&] { done = true; }, Fast(), true, &message),
      UnitOutcome::kComputed);
  EXPECT_FALSE(fs::exists(error));
  EXPECT_EQ(RunClaimedUnit(
                claim, error, "u", [&] { return done; }, [] { FAIL() << "ran twice"; }, Fast(),
                true, &message),
            UnitOutcome::kReused);
}

TEST(UnitClaim, WaitsForALiveHolderOrSaysBusy) {
  testing::TempDir dir;
  const fs::path claim = dir.path() / "u.claim";
  std::atomic<bool> done = false;
  auto held = UnitClaim::TryClaim(claim, Fast());
  ASSERT_NE(held, nullptr);
  EXPECT_EQ(RunClaimedUnit(
                claim, dir.path() / "error.txt", "u", [&] { return done.load(); }, [] {}, Fast(),
                /*wait=*/false, nullptr),
            UnitOutcome::kBusy);
  std::thread holder([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    done = true;
    held.reset();
  });
  int ran = 0;
  EXPECT_EQ(RunClaimedUnit(
                claim, dir.path() / "error.txt", "u", [&] { return done.load(); }, [&] { ++ran; },
                Fast(), /*wait=*/true, nullptr),
            UnitOutcome::kReused);
  holder.join();
  EXPECT_EQ(ran, 0);
}

// Several processes run the same list of units at once: each unit's work runs exactly once.
TEST(UnitClaim, ManyProcessesRunEachUnitOnce) {
  testing::TempDir dir;
  constexpr int kUnits = 12, kProcesses = 4;
  std::vector<pid_t> children;
  for (int p = 0; p < kProcesses; ++p) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      for (int u = 0; u < kUnits; ++u) {
        const fs::path done = dir.path() / ("unit" + std::to_string(u) + ".done");
        RunClaimedUnit(
            ClaimFile(dir.path(), "unit" + std::to_string(u)), dir.path() / "error.txt", "unit",
            [&] { return fs::exists(done); },
            [&] {
              std::ofstream(dir.path() / "log.txt", std::ios::app)
                  << "unit" << u << " " << ::getpid() << "\n";
              std::this_thread::sleep_for(std::chrono::milliseconds(20));
              std::ofstream(done) << "done\n";
            },
            Fast(), true, nullptr);
      }
      std::_Exit(0);
    }
    children.push_back(child);
  }
  for (const pid_t child : children) ::waitpid(child, nullptr, 0);
  std::ifstream log(dir.path() / "log.txt");
  std::map<std::string, int> runs;
  for (std::string unit, pid; log >> unit >> pid;) ++runs[unit];
  EXPECT_EQ(runs.size(), static_cast<size_t>(kUnits));
  for (const auto& [unit, count] : runs) EXPECT_EQ(count, 1) << unit;
}

TEST(UnitClaimOptions, StaleAfterMustSpanHeartbeats) {
  UnitClaimOptions o;
  o.stale_after_s = o.heartbeat_s;
  EXPECT_THROW(o.Check(), Error);
}

}  // namespace
}  // namespace areomap
