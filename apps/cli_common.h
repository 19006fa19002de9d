// Shared plumbing of the areomap subcommands: progress reporting, output folders, summaries.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

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

// Deletes the files in `out_dir` that an earlier run of the same command may have left and this
// run did not write: names in `optional_outputs` (a '*' in a name matches any run of characters,
// e.g. "cc_surface_*.png") that are not in `written`. Call it after this run's outputs are
// written and before its summary, so that a failing run leaves the earlier result whole and a
// succeeding one leaves no stale file beside its summary.
void RemoveStaleOutputs(const std::filesystem::path& out_dir,
                        const std::vector<std::string>& optional_outputs,
                        const std::vector<std::string>& written);

// Writes `summary` as out_dir/summary.json atomically.
void WriteSummary(const std::filesystem::path& out_dir, const nlohmann::json& summary);

}  // namespace areomap::cli
