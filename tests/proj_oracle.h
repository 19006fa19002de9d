// Runs PROJ's command-line tools (cs2cs, cct) on many points at once: the independent oracle
// for coordinate conversions.
#pragma once

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "test_support.h"

namespace areomap::testing {

// Feeds `points` (one "a b c" line each) to `command` on stdin and parses the first three
// numbers of each output line. Fails the test if the line count differs.
inline std::vector<Eigen::Vector3d> RunProjTool(const std::string& command,
                                                const std::vector<Eigen::Vector3d>& points) {
  const std::string input = std::filesystem::temp_directory_path() /
                            ("areomap-proj-" + std::to_string(::getpid()) + ".txt");
  {
    std::ofstream out(input);
    out.precision(17);
    for (const auto& p : points) out << p.x() << " " << p.y() << " " << p.z() << "\n";
  }
  const std::string output = RunCommand(command + " < " + input);
  std::filesystem::remove(input);
  std::vector<Eigen::Vector3d> result;
  std::istringstream lines(output);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    Eigen::Vector3d v = Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
    fields >> v.x() >> v.y() >> v.z();
    result.push_back(v);
  }
  EXPECT_EQ(result.size(), points.size()) << command;
  return result;
}

// Single-line form of a (possibly multi-line) WKT, quoted for the shell.
inline std::string ShellQuotedWkt(std::string wkt) {
  std::string flat;
  for (char c : wkt) {
    if (c != '\n') flat += c;
  }
  return "'" + flat + "'";
}

}  // namespace areomap::testing
