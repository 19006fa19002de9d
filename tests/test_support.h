// Helpers shared by the test executables.
#pragma once

#include <array>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "areomap/map/error.h"

namespace areomap::testing {

// ../shared/data beside the checkout; tests that need it call SKIP_WITHOUT_SHARED_DATA().
inline std::filesystem::path SharedDataDir() { return AREOMAP_SHARED_DATA_DIR; }

#define SKIP_WITHOUT_SHARED_DATA()                                                            \
  do {                                                                                        \
    if (!std::filesystem::is_directory(::areomap::testing::SharedDataDir())) {                \
      GTEST_SKIP() << "real sample data not found at " << ::areomap::testing::SharedDataDir() \
                   << " (../shared/data)";                                                    \
    }                                                                                         \
  } while (0)

// Runs a shell command and returns its standard output; fails the test on a non-zero exit.
inline std::string RunCommand(const std::string& command) {
  std::string output;
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  if (!pipe) {
    ADD_FAILURE() << "cannot run: " << command;
    return output;
  }
  std::array<char, 4096> buffer{};
  size_t n = 0;
  while ((n = fread(buffer.data(), 1, buffer.size(), pipe.get())) > 0)
    output.append(buffer.data(), n);
  const int status = pclose(pipe.release());
  EXPECT_EQ(status, 0) << "command failed: " << command;
  return output;
}

// The message of the areomap::Error that `function` throws, or "" if it throws none.
template <typename Function>
std::string ErrorMessageOf(Function function) {
  try {
    function();
  } catch (const ::areomap::Error& error) {
    return error.what();
  }
  return "";
}

// A fresh, empty temporary folder removed at the end of the test.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("areomap-" + std::string(info->test_suite_name()) + "-" + info->name() + "-" +
             std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace areomap::testing
