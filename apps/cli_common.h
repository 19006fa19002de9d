// Shared plumbing of the areomap subcommands: progress reporting, output folders, summaries.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "areomap/landmarks/rock_matching.h"
#include "areomap/map/output_folder.h"
#include "areomap/map/progress.h"

namespace areomap::cli {

struct GlobalOptions {
  bool quiet = false;      // --quiet: no progress, no human summary.
  bool overwrite = false;  // --overwrite: replace foreign files that carry an output's name.
};

// A progress callback that draws a bar on a terminal (stderr) and prints plain lines in
// 10 % steps otherwise; silent with --quiet.
ProgressCallback MakeProgressBar(const GlobalOptions& global, std::string title);

// The output-folder policy (areomap/map/output_folder.h) of `command` writing `outputs` (names in
// --out, "summary.json" added) from `inputs`, with --overwrite from the global options. A command
// opens its OutputFolder with these before any work, writes into folder.dir() and calls
// folder.Commit() once every output is written.
OutputFolderOptions OutputPolicy(const GlobalOptions& global, std::string command,
                                 std::vector<std::string> outputs,
                                 std::vector<std::filesystem::path> inputs);

// Writes `summary` as out_dir/summary.json atomically.
void WriteSummary(const std::filesystem::path& out_dir, const nlohmann::json& summary);

// Checks of numeric option values for CLI::Option::check(). CLI11 runs them on the text as given
// while it parses, before any command callback, and reports a refusal as
// "--flag: value <text> is not <rule>", e.g. "--max-range: value 0 is not a finite number > 0".
// Unlike CLI11's own CLI::PositiveNumber and CLI::Range, they refuse NaN and infinities (every
// comparison with NaN is false, so those let it through) and text that is not a number.
// Numbers are read as CLI11 converts them to double (strtod: "1e-3", "0x1p4"); integers as it
// converts them to an integral type (strtoll base 0: "12", "0x10"), so a fraction such as "1.5"
// is refused by the integer checks with their own message. On an option taking several values
// (a vector, or expected(3) with a delimiter) a check applies to each value, or only to the
// value at CLI::Validator::application_index. --help shows the accepted values after the type
// as an interval of finite numbers, e.g. "FLOAT:(0, inf)", "INT:[0, 65535]".

// Whether a bound of NumberIn belongs to the interval.
enum class Bound { kClosed, kOpen };

// Any finite number.
CLI::Validator FiniteNumber();
// A finite number > 0.
CLI::Validator PositiveNumber();
// A finite number >= 0.
CLI::Validator NonNegativeNumber();
// A finite number >= lo.
CLI::Validator NumberAtLeast(double lo);
// A finite number > lo.
CLI::Validator NumberAbove(double lo);
// A finite number in [lo, hi] (each bound inclusive unless Bound::kOpen), e.g.
// NumberIn(0, 0.5, Bound::kClosed, Bound::kOpen) for [0, 0.5).
CLI::Validator NumberIn(double lo, double hi, Bound lo_bound = Bound::kClosed,
                        Bound hi_bound = Bound::kClosed);
// A latitude: a finite number in [-90, 90] degrees.
CLI::Validator Latitude();
// A longitude: a finite number in [-360, 360] degrees (east or west, either domain).
CLI::Validator Longitude();
// An integer >= lo.
CLI::Validator IntegerAtLeast(long long lo);
// An integer in [lo, hi], both inclusive.
CLI::Validator IntegerIn(long long lo, long long hi);
// An odd integer in [lo, hi], both inclusive.
CLI::Validator OddIntegerIn(long long lo, long long hi);
// An integer among `values` (listed in the message as given).
CLI::Validator IntegerAmong(std::vector<long long> values);

// Checks the three values of an option read as "LAT,LON,H" (expected(3), delimiter ','):
// Latitude(), Longitude() and FiniteNumber() [m].
void CheckLatLonHeight(CLI::Option* option);

// The rock-pair rules that `run` and `rocks match` share: --compare-models
// (RockMatchingOptions::compare_models), --min-shape-points (min_shape_points) and
// --low-pair-height (low_pair_max_height_m), --pattern-vouch (pattern_vouch_deviation_m) and
// --pattern-vouch-votes (pattern_vouch_votes), each checked and with its default shown.
void AddRockPairOptions(CLI::App* command, RockMatchingOptions* matching);

}  // namespace areomap::cli
