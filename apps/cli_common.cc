#include "cli_common.h"

#include <algorithm>
#include <cstdio>
#include <iostream>

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

void PrepareOutputFolder(const std::filesystem::path& out_dir) {
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec || !std::filesystem::is_directory(out_dir)) {
    throw Error(out_dir.string() + ": cannot create output folder" +
                (ec ? ": " + ec.message() : std::string()));
  }
  if (::access(out_dir.c_str(), W_OK) != 0) {
    throw Error(out_dir.string() + ": output folder is not writable");
  }
}

namespace {

// Whether `name` matches `pattern`, in which one '*' stands for any run of characters.
bool MatchesPattern(const std::string& name, const std::string& pattern) {
  const size_t star = pattern.find('*');
  if (star == std::string::npos) return name == pattern;
  const std::string head = pattern.substr(0, star), tail = pattern.substr(star + 1);
  return name.size() >= head.size() + tail.size() && name.starts_with(head) && name.ends_with(tail);
}

}  // namespace

void RemoveStaleOutputs(const std::filesystem::path& out_dir,
                        const std::vector<std::string>& optional_outputs,
                        const std::vector<std::string>& written) {
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(out_dir, ec)) {
    if (!entry.is_regular_file()) continue;
    const std::string name = entry.path().filename().string();
    if (std::find(written.begin(), written.end(), name) != written.end()) continue;
    for (const std::string& pattern : optional_outputs) {
      if (!MatchesPattern(name, pattern)) continue;
      std::filesystem::remove(entry.path(), ec);
      if (ec)
        throw Error(entry.path().string() + ": cannot remove this stale output: " + ec.message());
      break;
    }
  }
}

void WriteSummary(const std::filesystem::path& out_dir, const nlohmann::json& summary) {
  WriteFileAtomically(out_dir / "summary.json", summary.dump(2) + "\n");
}

}  // namespace areomap::cli
