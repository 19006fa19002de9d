// Shared plumbing of the areomap subcommands: progress reporting, output folders, summaries.
#pragma once

#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "areomap/map/progress.h"

namespace areomap::cli {

struct GlobalOptions {
  bool quiet = false;  // --quiet: no progress, no human summary.
};

// A progress callback that draws a bar on a terminal (stderr) and prints plain lines in
// 10 % steps otherwise; silent with --quiet.
ProgressCallback MakeProgressBar(const GlobalOptions& global, std::string title);

// Creates `out_dir` if needed. Throws areomap::Error if it cannot be created or written.
void PrepareOutputFolder(const std::filesystem::path& out_dir);

// Writes `summary` as out_dir/summary.json atomically.
void WriteSummary(const std::filesystem::path& out_dir, const nlohmann::json& summary);

}  // namespace areomap::cli
