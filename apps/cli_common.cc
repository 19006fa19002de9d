#include "cli_common.h"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <iostream>
#include <optional>

#include <unistd.h>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap::cli {

ProgressCallback MakeProgressBar(const GlobalOptions& global, std::string title) {
  if (global.quiet) return [](double, std::string_view) { return true; };
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  auto last_step = std::make_shared<int>(-1);
  return [tty, title = std::move(title), last_step](double fraction, std::string_view stage) {
    const int percent = static_cast<int>(std::clamp(fraction, 0.0, 1.0) * 100.0 + 0.5);
    if (tty) {
      constexpr int kWidth = 30;
      const int filled = percent * kWidth / 100;
      std::fprintf(stderr, "\r%s [%.*s%*s] %3d%% %-24.24s", title.c_str(), filled,
                   "##############################", kWidth - filled, "", percent,
                   std::string(stage).c_str());
      if (percent >= 100) std::fprintf(stderr, "\n");
      std::fflush(stderr);
    } else if (percent / 10 != *last_step) {
      *last_step = percent / 10;
      std::fprintf(stderr, "%s: %d%% %s\n", title.c_str(), percent, std::string(stage).c_str());
    }
    return true;
  };
}

OutputFolderOptions OutputPolicy(const GlobalOptions& global, std::string command,
                                 std::vector<std::string> outputs,
                                 std::vector<std::filesystem::path> inputs) {
  OutputFolderOptions options;
  options.command = std::move(command);
  options.outputs = std::move(outputs);
  options.outputs.push_back("summary.json");
  options.inputs = std::move(inputs);
  options.overwrite = global.overwrite;
  return options;
}

void WriteSummary(const std::filesystem::path& out_dir, const nlohmann::json& summary) {
  WriteFileAtomically(out_dir / "summary.json", summary.dump(2) + "\n");
}

namespace {

// The shortest text that reads back as `v` (0.05, not 0.050000000000000003).
std::string Format(double v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), v);
  return std::string(buffer, result.ptr);
}

// `text` as CLI11 converts it to a double (all of it read), or nullopt.
std::optional<double> ParseNumber(const std::string& text) {
  if (text.empty()) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end != text.c_str() + text.size()) return std::nullopt;
  return v;
}

// `text` as CLI11 converts it to an integral type (strtoll, base 0, all of it read), or nullopt.
std::optional<long long> ParseInteger(const std::string& text) {
  if (text.empty()) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(text.c_str(), &end, 0);
  if (end != text.c_str() + text.size() || errno == ERANGE) return std::nullopt;
  return v;
}

// A check of finite numbers for which `ok` holds: "value 0 is not a finite number <rule>" (rule:
// "> 0", "in [0, 1]"); --help shows `interval` after the type ("FLOAT:(0, inf)").
CLI::Validator NumberCheck(const std::string& rule, const std::string& interval,
                           std::function<bool(double)> ok) {
  return CLI::Validator(
      [rule, ok = std::move(ok)](std::string& input) -> std::string {
        const std::optional<double> v = ParseNumber(input);
        if (v && std::isfinite(*v) && ok(*v)) return {};
        return "value " + input + " is not a finite number" + (rule.empty() ? "" : " " + rule);
      },
      interval);
}

// A check of integers for which `ok` holds: "value 4 is not an <noun> <rule>" (noun: "integer",
// "odd integer"; rule: ">= 1", "in [3, 11]"); --help shows `interval` after the type.
CLI::Validator IntegerCheck(const std::string& noun, const std::string& rule,
                            const std::string& interval, std::function<bool(long long)> ok) {
  return CLI::Validator(
      [noun, rule, ok = std::move(ok)](std::string& input) -> std::string {
        const std::optional<long long> v = ParseInteger(input);
        if (v && ok(*v)) return {};
        return "value " + input + " is not an " + noun + " " + rule;
      },
      interval);
}

}  // namespace

CLI::Validator FiniteNumber() {
  return NumberCheck("", "FINITE", [](double) { return true; });
}

CLI::Validator PositiveNumber() { return NumberAbove(0.0); }

CLI::Validator NonNegativeNumber() { return NumberAtLeast(0.0); }

CLI::Validator NumberAtLeast(double lo) {
  return NumberCheck(">= " + Format(lo), "[" + Format(lo) + ", inf)",
                     [lo](double v) { return v >= lo; });
}

CLI::Validator NumberAbove(double lo) {
  return NumberCheck("> " + Format(lo), "(" + Format(lo) + ", inf)",
                     [lo](double v) { return v > lo; });
}

CLI::Validator NumberIn(double lo, double hi, Bound lo_bound, Bound hi_bound) {
  const bool lo_open = lo_bound == Bound::kOpen, hi_open = hi_bound == Bound::kOpen;
  const std::string interval =
      (lo_open ? "(" : "[") + Format(lo) + ", " + Format(hi) + (hi_open ? ")" : "]");
  return NumberCheck("in " + interval, interval, [=](double v) {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  });
}

CLI::Validator Latitude() { return NumberIn(-90.0, 90.0); }

CLI::Validator Longitude() { return NumberIn(-360.0, 360.0); }

CLI::Validator IntegerAtLeast(long long lo) {
  return IntegerCheck("integer", ">= " + std::to_string(lo), "[" + std::to_string(lo) + ", inf)",
                      [lo](long long v) { return v >= lo; });
}

CLI::Validator IntegerIn(long long lo, long long hi) {
  const std::string interval = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  return IntegerCheck("integer", "in " + interval, interval,
                      [lo, hi](long long v) { return v >= lo && v <= hi; });
}

CLI::Validator OddIntegerIn(long long lo, long long hi) {
  const std::string interval = "[" + std::to_string(lo) + ", " + std::to_string(hi) + "]";
  return IntegerCheck("odd integer", "in " + interval, "odd " + interval,
                      [lo, hi](long long v) { return v >= lo && v <= hi && v % 2 != 0; });
}

CLI::Validator IntegerAmong(std::vector<long long> values) {
  std::string list;
  for (const long long v : values) list += (list.empty() ? "" : ", ") + std::to_string(v);
  return IntegerCheck("integer", "among " + list, "{" + list + "}",
                      [values = std::move(values)](long long v) {
                        return std::find(values.begin(), values.end(), v) != values.end();
                      });
}

void CheckLatLonHeight(CLI::Option* option) {
  // No descriptions: "FLOAT:in [-90, 90]:in [-360, 360]:FINITE" would not say which is which.
  option->check(Latitude().application_index(0).description(""));
  option->check(Longitude().application_index(1).description(""));
  option->check(FiniteNumber().application_index(2).description(""));
}

void AddRockPairOptions(CLI::App* command, RockMatchingOptions* matching) {
  command->add_flag("--compare-models", matching->compare_models,
                    "Compare rock pairs by their fitted models (eq. 3.28) rather than by their "
                    "measured heights (the default since 2026-12-05, docs/rocks.md)");
  command
      ->add_option("--min-shape-points", matching->min_shape_points,
                   "With --compare-models, eq. 3.28 compares two rock models only when both rest "
                   "on at least this many surface points; a pair with a model from fewer is "
                   "compared by its measured heights (0: eq. 3.28 for every pair)")
      ->check(IntegerAtLeast(0))
      ->capture_default_str();
  command
      ->add_option("--low-pair-height", matching->low_pair_max_height_m,
                   "A pair of rocks both measured lower than this is matched only between precise "
                   "peaks (0: no pair; before 2026-12-05 every pair with a rock under 15 cm was; "
                   "docs/rocks.md) [m]")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  command
      ->add_option(
          "--pattern-vouch", matching->pattern_vouch_deviation_m,
          "A rock pair whose translation lies within this of the global pattern's, with "
          "--pattern-vouch-votes votes, is matched even if it is a low pair seen from afar or "
          "its pair cost is above the limit (0: never; docs/rocks.md) [m]")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  command
      ->add_option("--pattern-vouch-votes", matching->pattern_vouch_votes,
                   "Rocks (the pair's own included) that must vote for a pair's translation "
                   "before the pattern vouches for it")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
}

}  // namespace areomap::cli
