#include "areomap/map/output_folder.h"

#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include <csignal>

#include <sys/wait.h>
#include <unistd.h>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap {
namespace {

namespace fs = std::filesystem;

class OutputFolderTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("areomap_output_folder_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_);
    out_ = root_ / "out";
  }
  void TearDown() override { fs::remove_all(root_); }

  static void Write(const fs::path& path, const std::string& text) {
    fs::create_directories(path.parent_path());
    std::ofstream(path, std::ios::binary) << text;
  }
  static std::string Read(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  static OutputFolderOptions Stereo() {
    OutputFolderOptions o;
    o.command = "stereo";
    o.outputs = {"points.ply", "tie_points.csv", "cc_surface_*.png", "summary.json"};
    return o;
  }
  // One complete run of `options` writing `files` (name -> content).
  void RunOnce(const OutputFolderOptions& options,
               const std::vector<std::pair<std::string, std::string>>& files) {
    OutputFolder folder(out_, options);
    for (const auto& [name, text] : files) Write(folder / name, text);
    folder.Commit();
  }

  fs::path root_, out_;
};

TEST_F(OutputFolderTest, RefusesAForeignFileUnderAnOutputNameBeforeAnyWork) {
  Write(out_ / "points.ply", "user's own cloud");
  try {
    OutputFolder folder(out_, Stereo());
    FAIL() << "expected a refusal";
  } catch (const Error& e) {
    const std::string message = e.what();
    EXPECT_NE(message.find("points.ply"), std::string::npos) << message;
    EXPECT_NE(message.find("--overwrite"), std::string::npos) << message;
  }
  EXPECT_EQ(Read(out_ / "points.ply"), "user's own cloud");
  EXPECT_EQ(std::distance(fs::directory_iterator(out_), fs::directory_iterator()), 1);
}

TEST_F(OutputFolderTest, OverwriteReplacesAForeignFileUnderAnOutputName) {
  Write(out_ / "points.ply", "user's own cloud");
  OutputFolderOptions options = Stereo();
  options.overwrite = true;
  RunOnce(options, {{"points.ply", "new"}});
  EXPECT_EQ(Read(out_ / "points.ply"), "new");
}

TEST_F(OutputFolderTest, ReplacesItsOwnEarlierOutputsAndRemovesOnlyItsOwnStaleOnes) {
  RunOnce(Stereo(), {{"points.ply", "1"}, {"tie_points.csv", "1"}, {"cc_surface_0.png", "1"}});
  Write(out_ / "cc_surface_holiday.png", "user's photo");
  Write(out_ / "notes.txt", "user's notes");
  RunOnce(Stereo(), {{"points.ply", "2"}});
  EXPECT_EQ(Read(out_ / "points.ply"), "2");
  EXPECT_FALSE(fs::exists(out_ / "tie_points.csv"));
  EXPECT_FALSE(fs::exists(out_ / "cc_surface_0.png"));
  EXPECT_EQ(Read(out_ / "cc_surface_holiday.png"), "user's photo");
  EXPECT_EQ(Read(out_ / "notes.txt"), "user's notes");
}

TEST_F(OutputFolderTest, RefusesAtCommitAPatternNameHeldByAForeignFileAndMovesNothing) {
  RunOnce(Stereo(), {{"points.ply", "1"}});
  Write(out_ / "cc_surface_0.png", "user's file");
  OutputFolder folder(out_, Stereo());
  Write(folder / "points.ply", "2");
  Write(folder / "cc_surface_0.png", "2");
  EXPECT_THROW(folder.Commit(), Error);
  EXPECT_EQ(Read(out_ / "points.ply"), "1");
  EXPECT_EQ(Read(out_ / "cc_surface_0.png"), "user's file");
}

TEST_F(OutputFolderTest, AFailedRunLeavesThePreviousResultWhole) {
  RunOnce(Stereo(), {{"points.ply", "good"}, {"summary.json", "good"}});
  {
    OutputFolder folder(out_, Stereo());
    Write(folder / "points.ply", "half");
    // No Commit(): the command failed.
  }
  EXPECT_EQ(Read(out_ / "points.ply"), "good");
  EXPECT_EQ(Read(out_ / "summary.json"), "good");
  for (const auto& entry : fs::directory_iterator(out_)) {
    EXPECT_FALSE(entry.path().filename().string().starts_with(".areomap-staging"));
    EXPECT_NE(entry.path().filename(), OutputFolder::kLockName);
  }
}

TEST_F(OutputFolderTest, AFailedRunInANewFolderLeavesNoFolder) {
  { OutputFolder folder(out_, Stereo()); }
  EXPECT_FALSE(fs::exists(out_));
}

TEST_F(OutputFolderTest, RefusesAnInputThatCarriesAnOutputNameEvenWithOverwrite) {
  Write(out_ / "tie_points.csv", "input");
  OutputFolderOptions options = Stereo();
  options.inputs = {out_ / "tie_points.csv"};
  options.overwrite = true;
  EXPECT_THROW(OutputFolder(out_, options), Error);
  EXPECT_EQ(Read(out_ / "tie_points.csv"), "input");
}

TEST_F(OutputFolderTest, AcceptsAnInputInTheFolderUnderAnotherName) {
  Write(out_ / "left.png", "input");
  OutputFolderOptions options = Stereo();
  options.inputs = {out_ / "left.png"};
  RunOnce(options, {{"points.ply", "1"}});
  EXPECT_EQ(Read(out_ / "left.png"), "input");
}

TEST_F(OutputFolderTest, RefusesTheInputFolderAndAFolderInsideIt) {
  fs::create_directories(root_ / "mission");
  OutputFolderOptions options = Stereo();
  options.inputs = {root_ / "mission"};
  EXPECT_THROW(OutputFolder(root_ / "mission", options), Error);
  EXPECT_THROW(OutputFolder(root_ / "mission" / "run", options), Error);
  EXPECT_FALSE(fs::exists(root_ / "mission" / "run"));
}

TEST_F(OutputFolderTest, RefusesAMissionFolderItDidNotWrite) {
  Write(out_ / "mission.json", "{}");
  EXPECT_THROW(OutputFolder(out_, Stereo()), Error);
  OutputFolderOptions simulate;
  simulate.command = "simulate";
  simulate.outputs = {"mission.json", "sites/"};
  simulate.overwrite = true;  // The first run over a foreign mission.json.
  RunOnce(simulate, {{"mission.json", "1"}, {"sites/site_000/a.png", "1"}});
  simulate.overwrite = false;
  RunOnce(simulate, {{"mission.json", "2"}, {"sites/site_001/a.png", "2"}});
  EXPECT_EQ(Read(out_ / "mission.json"), "2");
  EXPECT_FALSE(fs::exists(out_ / "sites/site_000/a.png"));
  EXPECT_THROW(OutputFolder(out_, Stereo()), Error);
}

TEST_F(OutputFolderTest, RefusesAFolderAnotherProcessIsWritingInto) {
  OutputFolder first(out_, Stereo());
  try {
    OutputFolder second(out_, Stereo());
    FAIL() << "expected a refusal";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("pid " + std::to_string(::getpid())), std::string::npos)
        << e.what();
  }
}

TEST_F(OutputFolderTest, ALockLeftByADeadProcessIsFree) {
  Write(out_ / OutputFolder::kLockName, "999999\n");  // No process holds it.
  RunOnce(Stereo(), {{"points.ply", "1"}});
  EXPECT_EQ(Read(out_ / "points.ply"), "1");
  EXPECT_FALSE(fs::exists(out_ / OutputFolder::kLockName));
}

TEST_F(OutputFolderTest, RemovesTheTemporaryFilesAKilledRunLeft) {
  RunOnce(Stereo(), {{"points.ply", "1"}});
  Write(out_ / ".tmp-4242-points.ply", "half");
  Write(out_ / ".areomap-staging-4242" / "points.ply", "half");
  Write(out_ / "tmp-notes.txt", "user's");
  { OutputFolder folder(out_, Stereo()); }
  EXPECT_FALSE(fs::exists(out_ / ".tmp-4242-points.ply"));
  EXPECT_FALSE(fs::exists(out_ / ".areomap-staging-4242"));
  EXPECT_EQ(Read(out_ / "tmp-notes.txt"), "user's");
}

TEST_F(OutputFolderTest, SigintDuringAWriteRemovesTheStagingFolderAndTheLock) {
  RunOnce(Stereo(), {{"points.ply", "good"}});
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    OutputFolder folder(out_, Stereo());
    Write(folder / "points.ply", "half");
    std::raise(SIGINT);
    ::_exit(0);  // Not reached: the handler ends the process with the signal.
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT);
  EXPECT_EQ(Read(out_ / "points.ply"), "good");
  for (const auto& entry : fs::directory_iterator(out_)) {
    EXPECT_FALSE(entry.path().filename().string().starts_with(".areomap-staging"));
    EXPECT_NE(entry.path().filename(), OutputFolder::kLockName);
  }
}

TEST_F(OutputFolderTest, AnInPlaceRunKilledBeforeCommitIsResumedNotRefused) {
  OutputFolderOptions run;
  run.command = "run";
  run.outputs = {"sites/", "summary.json"};
  run.in_place = true;
  {
    OutputFolder folder(out_, run);
    Write(folder / "sites/site_000/unit.json", "done");
    Write(folder / "sites/site_001/.tmp-4242-points.ply", "half");  // Killed while writing.
  }
  {
    OutputFolder folder(out_, run);  // Not refused: sites/ is the run's.
    EXPECT_EQ(Read(out_ / "sites/site_000/unit.json"), "done");
    EXPECT_FALSE(fs::exists(out_ / "sites/site_001/.tmp-4242-points.ply"));
    Write(folder / "summary.json", "1");
    folder.Commit();
  }
  EXPECT_EQ(Read(out_ / "summary.json"), "1");
  OutputFolderOptions other = Stereo();
  other.outputs.push_back("sites/");
  EXPECT_NO_THROW(OutputFolder(out_, other));  // An areomap folder, not a foreign one.
}

TEST_F(OutputFolderTest, AdoptsAFolderAnEarlierVersionWroteForItsFixedNamesOnly) {
  Write(out_ / "summary.json", R"({"command": "stereo"})");
  Write(out_ / "points.ply", "old");
  Write(out_ / "tie_points.csv", "old");
  Write(out_ / "cc_surface_holiday.png", "user's");
  RunOnce(Stereo(), {{"points.ply", "new"}});
  EXPECT_EQ(Read(out_ / "points.ply"), "new");
  EXPECT_FALSE(fs::exists(out_ / "tie_points.csv"));  // The earlier run's optional output.
  EXPECT_EQ(Read(out_ / "cc_surface_holiday.png"), "user's");
  // Another command's folder is not adopted.
  fs::remove(out_ / OutputFolder::kManifestName);
  OutputFolderOptions other = Stereo();
  other.command = "dtm";
  EXPECT_THROW(OutputFolder(out_, other), Error);
}

TEST_F(OutputFolderTest, SigintInAFolderItMadeLeavesNoFolder) {
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    OutputFolder folder(out_, Stereo());
    Write(folder / "points.ply", "half");
    std::raise(SIGTERM);
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM);
  EXPECT_FALSE(fs::exists(out_));
}

TEST_F(OutputFolderTest, SigintDuringAnInPlaceWriteRemovesTheTemporaryFile) {
  OutputFolderOptions run;
  run.command = "run";
  run.outputs = {"sites/"};
  run.in_place = true;
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    OutputFolder folder(out_, run);
    fs::create_directories(folder / "sites/site_000");
    AtomicFile file(folder / "sites/site_000/points.ply");
    Write(file.temp_path(), "half");
    std::raise(SIGINT);
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT);
  ASSERT_TRUE(fs::is_directory(out_ / "sites/site_000"));
  EXPECT_TRUE(fs::is_empty(out_ / "sites/site_000"));
  EXPECT_FALSE(fs::exists(out_ / OutputFolder::kLockName));
}

TEST_F(OutputFolderTest, RefusesAFileWhereItWritesAFolder) {
  Write(out_ / "sites", "user's file");
  OutputFolderOptions options;
  options.command = "run";
  options.outputs = {"sites/"};
  options.in_place = true;
  options.overwrite = true;
  EXPECT_THROW(OutputFolder(out_, options), Error);
  EXPECT_EQ(Read(out_ / "sites"), "user's file");
}

TEST_F(OutputFolderTest, RefusesAnOutFolderThatIsAFile) {
  Write(out_, "a file");
  EXPECT_THROW(OutputFolder(out_, Stereo()), Error);
  EXPECT_EQ(Read(out_), "a file");
}

TEST(OutputNameMatches, FollowsNamesPatternsAndFolders) {
  EXPECT_TRUE(OutputNameMatches("points.ply", "points.ply"));
  EXPECT_TRUE(OutputNameMatches("cc_surface_3.png", "cc_surface_*.png"));
  EXPECT_FALSE(OutputNameMatches("cc_surface_3.png.bak", "cc_surface_*.png"));
  EXPECT_FALSE(OutputNameMatches("cc_surface_a/b.png", "cc_surface_*.png"));
  EXPECT_TRUE(OutputNameMatches("sites", "sites/"));
  EXPECT_TRUE(OutputNameMatches("sites/site_000/points.ply", "sites/"));
  EXPECT_FALSE(OutputNameMatches("sites.csv", "sites/"));
}

}  // namespace
}  // namespace areomap
