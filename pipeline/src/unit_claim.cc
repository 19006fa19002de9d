#include "areomap/pipeline/unit_claim.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <random>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"

namespace areomap {

namespace fs = std::filesystem;

void UnitClaimOptions::Check() const {
  if (!(heartbeat_s > 0.0) || !std::isfinite(heartbeat_s)) {
    throw Error("claim heartbeat_s: expected a positive number of seconds");
  }
  if (!(stale_after_s >= 2.0 * heartbeat_s) || !std::isfinite(stale_after_s)) {
    throw Error("claim stale_after_s: expected at least two heartbeats (" +
                std::to_string(2.0 * heartbeat_s) + " s)");
  }
  if (!(poll_s > 0.0) || !std::isfinite(poll_s)) {
    throw Error("claim poll_s: expected a positive number of seconds");
  }
}

std::string ClaimHolder::ToString() const {
  std::ostringstream text;
  text << host << ":" << pid << " (touched " << std::lround(age_s) << " s ago)";
  return text.str();
}

namespace {

std::string HostName() {
  char name[256] = {};
  if (::gethostname(name, sizeof(name) - 1) != 0) return "unknown-host";
  return name;
}

// The start time of process `pid` (field 22 of /proc/PID/stat, clock ticks after boot); 0 when
// the process does not exist or /proc does not tell.
long long ProcessStartTime(long pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string stat;
  if (!in || !std::getline(in, stat)) return 0;
  const size_t name_end = stat.rfind(')');  // The command name may hold spaces and ')'.
  if (name_end == std::string::npos) return 0;
  std::istringstream fields(stat.substr(name_end + 1));
  std::string field;
  for (int index = 3; index <= 22 && fields >> field; ++index) {
    if (index == 22) return std::atoll(field.c_str());
  }
  return 0;
}

std::string RandomToken() {
  std::random_device device;
  std::mt19937_64 generator((static_cast<uint64_t>(device()) << 32) ^ device() ^
                            static_cast<uint64_t>(::getpid()));
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(generator()));
  return text;
}

// Creates `path` holding `content` if no such file exists; false when it exists.
bool CreateExclusive(const fs::path& path, const std::string& content) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    if (errno == EEXIST) return false;
    throw Error(path.string() + ": cannot create the claim: " + std::strerror(errno));
  }
  const ssize_t written = ::write(fd, content.data(), content.size());
  const int saved = errno;
  ::close(fd);
  if (written != static_cast<ssize_t>(content.size())) {
    fs::remove(path);
    throw Error(path.string() + ": cannot write the claim: " + std::strerror(saved));
  }
  return true;
}

std::optional<std::string> ReadText(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return std::nullopt;
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// Seconds since `path` was last modified; nullopt when it does not exist.
std::optional<double> AgeSeconds(const fs::path& path) {
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) return std::nullopt;
  struct timespec now {};
  ::clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<double>(now.tv_sec - info.st_mtim.tv_sec) +
         1e-9 * static_cast<double>(now.tv_nsec - info.st_mtim.tv_nsec);
}

std::optional<ClaimHolder> ParseHolder(const std::string& text) {
  const nlohmann::json parsed = nlohmann::json::parse(text, nullptr, false);
  if (!parsed.is_object()) return std::nullopt;
  ClaimHolder holder;
  try {
    holder.host = parsed.at("host").get<std::string>();
    holder.pid = parsed.at("pid").get<long>();
    holder.process_start = parsed.value("process_start", 0LL);
    holder.token = parsed.at("token").get<std::string>();
  } catch (const nlohmann::json::exception&) {
    return std::nullopt;
  }
  return holder;
}

}  // namespace

std::optional<ClaimHolder> ReadClaimHolder(const fs::path& claim_file) {
  const std::optional<std::string> text = ReadText(claim_file);
  const std::optional<double> age = AgeSeconds(claim_file);
  if (!text || !age) return std::nullopt;
  std::optional<ClaimHolder> holder = ParseHolder(*text);
  if (holder) holder->age_s = *age;
  return holder;
}

bool IsStale(const ClaimHolder& holder, const UnitClaimOptions& options) {
  if (holder.age_s > options.stale_after_s) return true;
  if (holder.host != HostName() || holder.pid <= 0) return false;
  // On this host: the holder is gone, or its pid now belongs to another process.
  if (::kill(static_cast<pid_t>(holder.pid), 0) != 0 && errno == ESRCH) return true;
  const long long start = ProcessStartTime(holder.pid);
  return holder.process_start != 0 && start != 0 && start != holder.process_start;
}

std::unique_ptr<UnitClaim> UnitClaim::TryClaim(const fs::path& claim_file,
                                               const UnitClaimOptions& options) {
  std::error_code ec;
  fs::create_directories(claim_file.parent_path(), ec);
  if (ec) {
    throw Error(claim_file.parent_path().string() +
                ": cannot create the claims folder: " + ec.message());
  }
  const std::string token = RandomToken();
  const std::string content = nlohmann::json{{"host", HostName()},
                                             {"pid", static_cast<long>(::getpid())},
                                             {"process_start", ProcessStartTime(::getpid())},
                                             {"token", token}}
                                  .dump() +
                              "\n";
  const auto claimed = [&] {
    return std::unique_ptr<UnitClaim>(new UnitClaim(claim_file, token, options.heartbeat_s));
  };
  const fs::path takeover = claim_file.string() + ".takeover";
  for (int attempt = 0; attempt < 4; ++attempt) {
    if (CreateExclusive(claim_file, content)) return claimed();
    const std::optional<std::string> held = ReadText(claim_file);
    const std::optional<double> age = AgeSeconds(claim_file);
    if (!held || !age) continue;  // Released meanwhile: try again.
    std::optional<ClaimHolder> holder = ParseHolder(*held);
    // A claim that cannot be parsed is being written, or was left half-written by a holder that
    // died: stale only by its age.
    const bool stale =
        holder ? (holder->age_s = *age, IsStale(*holder, options)) : *age > options.stale_after_s;
    if (!stale) return nullptr;
    if (!CreateExclusive(takeover, content)) {
      const std::optional<double> takeover_age = AgeSeconds(takeover);
      if (takeover_age && *takeover_age > options.stale_after_s) {
        fs::remove(takeover, ec);
        continue;
      }
      return nullptr;  // Another process is taking it over.
    }
    // Replace the claim only if it is still the one judged stale.
    if (ReadText(claim_file) == held) fs::remove(claim_file, ec);
    const bool ok = CreateExclusive(claim_file, content);
    fs::remove(takeover, ec);
    return ok ? claimed() : nullptr;
  }
  return nullptr;
}

UnitClaim::UnitClaim(fs::path file, std::string token, double heartbeat_s)
    : file_(std::move(file)), token_(std::move(token)), heartbeat_s_(heartbeat_s) {
  heartbeat_ = std::thread([this] { Heartbeat(); });
}

void UnitClaim::Heartbeat() {
  std::unique_lock lock(mutex_);
  while (!wake_.wait_for(lock, std::chrono::duration<double>(heartbeat_s_),
                         [this] { return stop_; })) {
    ::utimensat(AT_FDCWD, file_.c_str(), nullptr, 0);  // Touch: now.
  }
}

UnitClaim::~UnitClaim() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  heartbeat_.join();
  const std::optional<std::string> text = ReadText(file_);
  const std::optional<ClaimHolder> holder = text ? ParseHolder(*text) : std::nullopt;
  std::error_code ec;
  if (holder && holder->token == token_) fs::remove(file_, ec);
}

const char* ToString(UnitOutcome outcome) {
  switch (outcome) {
    case UnitOutcome::kComputed:
      return "computed";
    case UnitOutcome::kReused:
      return "reused";
    case UnitOutcome::kFailed:
      return "failed";
    case UnitOutcome::kBusy:
      return "busy";
  }
  return "?";
}

void WriteUnitError(const fs::path& error_file, const std::string& unit,
                    const std::string& message) {
  std::error_code ec;
  fs::create_directories(error_file.parent_path(), ec);
  const std::time_t now = std::time(nullptr);
  char when[32];
  std::strftime(when, sizeof(when), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  std::ostringstream text;
  text << "unit: " << unit << "\n"
       << "host: " << HostName() << "\npid: " << ::getpid() << "\ntime: " << when << "\n"
       << "error: " << message << "\n";
  try {
    WriteFileAtomically(error_file, text.str());
  } catch (const std::exception&) {
    // The unit's failure is still reported to the caller.
  }
}

UnitOutcome RunClaimedUnit(const fs::path& claim_file, const fs::path& error_file,
                           const std::string& unit, const std::function<bool()>& is_done,
                           const std::function<void()>& work, const UnitClaimOptions& options,
                           bool wait, std::string* error) {
  while (true) {
    if (is_done()) return UnitOutcome::kReused;
    const std::unique_ptr<UnitClaim> claim = UnitClaim::TryClaim(claim_file, options);
    if (!claim) {
      if (!wait) return UnitOutcome::kBusy;
      std::this_thread::sleep_for(std::chrono::duration<double>(options.poll_s));
      continue;
    }
    if (is_done()) return UnitOutcome::kReused;  // Finished by the holder just released.
    std::error_code ec;
    fs::remove(error_file, ec);
    try {
      work();
      return UnitOutcome::kComputed;
    } catch (const std::exception& e) {
      WriteUnitError(error_file, unit, e.what());
      if (error) *error = e.what();
      return UnitOutcome::kFailed;
    }
  }
}

}  // namespace areomap
