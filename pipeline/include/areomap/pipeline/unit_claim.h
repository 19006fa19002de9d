// Claims on work units shared by many processes on many hosts over one shared filesystem (NFS,
// Lustre), so that each unit of a plan (work_plan.h) runs exactly once however many executors
// work on the plan, and a unit whose holder died runs again.
//
// A claim is a small file created with O_CREAT | O_EXCL (atomic on local filesystems and on NFS
// v3 and later) holding the holder's host, pid, process start time and a random token. While the
// work runs, a heartbeat thread touches the file every heartbeat_s. A claim is stale, and is
// taken over, when
//  - its holder ran on this host and that process is gone (or the pid now belongs to a process
//    started at another time): at once, e.g. after SIGKILL or a crash;
//  - it was last touched more than stale_after_s ago (a holder on another host that died, or a
//    host that went down). Hosts' clocks are taken to agree within a few seconds (NTP, as
//    cluster nodes run); stale_after_s should be several heartbeats.
// Two processes that find the same stale claim take it over one at a time: a takeover first
// creates `<claim>.takeover` exclusively, then checks that the claim still holds the token it
// judged stale before replacing it. A takeover file older than stale_after_s is itself stale.
//
// Failure: filesystem errors other than "the claim exists" throw areomap::Error naming the file.
#pragma once

#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

namespace areomap {

struct UnitClaimOptions {
  double heartbeat_s = 10.0;     // How often a holder touches its claim [s].
  double stale_after_s = 120.0;  // A claim untouched this long is stale [s].
  double poll_s = 2.0;           // How often a waiting process looks again [s].
  void Check() const;            // Throws areomap::Error naming the field.
};

// Who holds a claim, as its file says.
struct ClaimHolder {
  std::string host;
  long pid = 0;
  long long process_start = 0;  // The holder's start time (clock ticks after boot), 0 if unknown.
  std::string token;
  double age_s = 0.0;            // Since the file was last touched [s].
  std::string ToString() const;  // "host:pid (touched 3 s ago)".
};

// The holder recorded in `claim_file`; nullopt when there is no such file or it cannot be parsed
// (a holder still writing it).
std::optional<ClaimHolder> ReadClaimHolder(const std::filesystem::path& claim_file);
// Whether `holder` is stale by the rules above.
bool IsStale(const ClaimHolder& holder, const UnitClaimOptions& options);

class UnitClaim {
 public:
  // Claims `claim_file` (its folder is created), taking over a stale claim; nullptr when a live
  // holder has it. The claim is held, and its heartbeat runs, until the object is destroyed.
  static std::unique_ptr<UnitClaim> TryClaim(const std::filesystem::path& claim_file,
                                             const UnitClaimOptions& options);
  ~UnitClaim();  // Stops the heartbeat; removes the file if it still holds this claim's token.
  UnitClaim(const UnitClaim&) = delete;
  UnitClaim& operator=(const UnitClaim&) = delete;

  const std::string& token() const { return token_; }

 private:
  UnitClaim(std::filesystem::path file, std::string token, double heartbeat_s);
  void Heartbeat();

  std::filesystem::path file_;
  std::string token_;
  double heartbeat_s_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::thread heartbeat_;
};

// How a claimed unit went.
enum class UnitOutcome { kComputed, kReused, kFailed, kBusy };
const char* ToString(UnitOutcome outcome);

// Runs one unit under its claim: returns kReused when `is_done()` says it is finished (before or
// after claiming); otherwise claims `claim_file` and runs `work`. While a live process holds
// the claim, waits for it (polling every poll_s) when `wait`, else returns kBusy. When `work`
// throws, writes `error_file` (what failed, the message, host, pid, time) and returns kFailed
// with the message in `*error`; a unit that then succeeds removes the error file first (it is
// this mechanism's own). The claim is released either way.
UnitOutcome RunClaimedUnit(const std::filesystem::path& claim_file,
                           const std::filesystem::path& error_file, const std::string& unit,
                           const std::function<bool()>& is_done, const std::function<void()>& work,
                           const UnitClaimOptions& options, bool wait, std::string* error);

// Writes `error_file` (its folder created): the unit, host, pid, UTC time and `message`. Never
// throws: the failure is reported to the caller anyway.
void WriteUnitError(const std::filesystem::path& error_file, const std::string& unit,
                    const std::string& message);

}  // namespace areomap
