#include "areomap/map/atomic_file.h"

#include <array>
#include <atomic>
#include <cstring>
#include <fstream>
#include <system_error>

#include <unistd.h>

#include "areomap/map/error.h"
#include "atomic_file_registry.h"

namespace areomap {
namespace {

// A fixed table of the live temporary files' paths that a signal handler can read without
// allocating: a slot is free (0), being filled (1) or holds a path (2). More live files than
// slots go unregistered (the next run still removes them).
struct TempSlot {
  std::atomic<int> state{0};
  char path[4096];
};
std::array<TempSlot, 256> g_temp_slots;

void RegisterTemp(const std::filesystem::path& path) {
  const std::string text = path.string();
  if (text.size() >= sizeof(TempSlot::path)) return;
  for (TempSlot& slot : g_temp_slots) {
    int expected = 0;
    if (slot.state.compare_exchange_strong(expected, 1)) {
      std::memcpy(slot.path, text.c_str(), text.size() + 1);
      slot.state.store(2);
      return;
    }
  }
}

// Temporary paths are unique (pid and final name): the slot holding `path` is this file's.
void UnregisterTemp(const std::filesystem::path& path) {
  const std::string text = path.string();
  for (TempSlot& slot : g_temp_slots) {
    if (slot.state.load() == 2 && std::strcmp(slot.path, text.c_str()) == 0) {
      slot.state.store(0);
      return;
    }
  }
}

}  // namespace

namespace internal {

void RemoveAtomicTempsInHandler() {
  for (TempSlot& slot : g_temp_slots) {
    if (slot.state.load() == 2) ::unlink(slot.path);
  }
}

}  // namespace internal

AtomicFile::AtomicFile(std::filesystem::path final_path) : final_path_(std::move(final_path)) {
  std::filesystem::path folder = final_path_.parent_path();
  if (folder.empty()) folder = ".";
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    throw Error(final_path_.string() + ": cannot write: folder '" + folder.string() +
                "' does not exist");
  }
  if (::access(folder.c_str(), W_OK) != 0) {
    throw Error(final_path_.string() + ": cannot write: folder '" + folder.string() +
                "' is not writable");
  }
  temp_path_ =
      folder / (".tmp-" + std::to_string(::getpid()) + "-" + final_path_.filename().string());
  RegisterTemp(temp_path_);
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    std::error_code ignored;
    std::filesystem::remove(temp_path_, ignored);
  }
  UnregisterTemp(temp_path_);
}

void AtomicFile::Commit() {
  std::error_code ec;
  std::filesystem::rename(temp_path_, final_path_, ec);
  if (ec) {
    throw Error(final_path_.string() +
                ": cannot move the finished file into place: " + ec.message());
  }
  committed_ = true;
}

void WriteFileAtomically(const std::filesystem::path& path, std::string_view content) {
  AtomicFile file(path);
  {
    std::ofstream out(file.temp_path(), std::ios::binary);
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.close();
    if (!out) throw Error(path.string() + ": write failed");
  }
  file.Commit();
}

}  // namespace areomap
