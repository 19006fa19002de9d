#include "areomap/map/output_folder.h"

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "atomic_file_registry.h"

namespace areomap {

namespace fs = std::filesystem;

namespace {

constexpr const char* kStagingPrefix = ".areomap-staging-";

// What the signal handler removes: the staging folder and the lock file of the open folder.
// Plain arrays, set before the handler can see them (one output folder per process at a time).
char g_signal_staging[4096];
char g_signal_lock[4096];
char g_signal_folder[4096];  // The output folder when this process made it (removed if empty).
volatile std::sig_atomic_t g_signal_armed = 0;

// Removes `path` and everything under it with async-signal-safe calls only.
void RemoveTreeInHandler(const char* path) {
  if (::unlink(path) == 0) return;
  const int dir_fd = ::open(path, O_RDONLY | O_DIRECTORY | O_NOFOLLOW);
  if (dir_fd < 0) return;
  // getdents through fdopendir is not on the async-signal-safe list but does not allocate on
  // glibc after the first call; the staging folder is flat or shallow, so recursion is bounded.
  DIR* dir = ::fdopendir(dir_fd);
  if (dir == nullptr) {
    ::close(dir_fd);
    return;
  }
  char child[4096];
  while (const dirent* entry = ::readdir(dir)) {
    if (std::strcmp(entry->d_name, ".") == 0 || std::strcmp(entry->d_name, "..") == 0) continue;
    const size_t a = std::strlen(path), b = std::strlen(entry->d_name);
    if (a + b + 2 > sizeof(child)) continue;
    std::memcpy(child, path, a);
    child[a] = '/';
    std::memcpy(child + a + 1, entry->d_name, b + 1);
    RemoveTreeInHandler(child);
  }
  ::closedir(dir);
  ::rmdir(path);
}

void OnSignal(int signal_number) {
  if (g_signal_armed) {
    internal::RemoveAtomicTempsInHandler();  // In place (the run): the files being written.
    if (g_signal_staging[0] != '\0') RemoveTreeInHandler(g_signal_staging);
    if (g_signal_lock[0] != '\0') ::unlink(g_signal_lock);
    if (g_signal_folder[0] != '\0') ::rmdir(g_signal_folder);  // Only when empty.
  }
  std::signal(signal_number, SIG_DFL);
  std::raise(signal_number);
}

void CopyForHandler(char* target, size_t size, const fs::path& path) {
  const std::string text = path.string();
  if (text.size() >= size) {
    target[0] = '\0';
    return;
  }
  std::memcpy(target, text.c_str(), text.size() + 1);
}

void ArmSignalCleanup(const fs::path& staging, const fs::path& lock, const fs::path& folder) {
  g_signal_armed = 0;
  CopyForHandler(g_signal_staging, sizeof(g_signal_staging), staging);
  CopyForHandler(g_signal_lock, sizeof(g_signal_lock), lock);
  CopyForHandler(g_signal_folder, sizeof(g_signal_folder), folder);
  g_signal_armed = 1;
  struct sigaction action {};
  action.sa_handler = OnSignal;
  sigemptyset(&action.sa_mask);
  ::sigaction(SIGINT, &action, nullptr);
  ::sigaction(SIGTERM, &action, nullptr);
}

void DisarmSignalCleanup() { g_signal_armed = 0; }

// `path` made absolute and free of "." and ".." and symbolic links as far as it exists.
fs::path Normal(const fs::path& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) p = fs::absolute(path).lexically_normal();
  // "a/b/" and "a/b" name the same folder.
  if (!p.has_filename() && p.has_parent_path() && p != p.root_path()) p = p.parent_path();
  return p;
}

// Whether `inner` is `outer` or lies under it (both Normal()).
bool IsWithin(const fs::path& inner, const fs::path& outer) {
  auto o = outer.begin();
  auto i = inner.begin();
  for (; o != outer.end(); ++o, ++i) {
    if (i == inner.end() || *i != *o) return false;
  }
  return true;
}

// A temporary file of AtomicFile: ".tmp-<digits>-<name>".
bool IsAtomicTemp(const std::string& name) {
  if (!name.starts_with(".tmp-")) return false;
  size_t k = 5;
  while (k < name.size() && name[k] >= '0' && name[k] <= '9') ++k;
  return k > 5 && k < name.size() && name[k] == '-';
}

std::string Relative(const fs::path& path, const fs::path& base) {
  return path.lexically_relative(base).generic_string();
}

std::string Quote(const fs::path& path) { return "'" + path.string() + "'"; }

}  // namespace

bool OutputNameMatches(const std::string& relative, const std::string& pattern) {
  if (pattern.ends_with('/')) {
    return relative == pattern.substr(0, pattern.size() - 1) || relative.starts_with(pattern);
  }
  const size_t star = pattern.find('*');
  if (star == std::string::npos) return relative == pattern;
  const std::string head = pattern.substr(0, star), tail = pattern.substr(star + 1);
  if (relative.size() < head.size() + tail.size()) return false;
  if (!relative.starts_with(head) || !relative.ends_with(tail)) return false;
  // '*' stays within one path component.
  const std::string middle =
      relative.substr(head.size(), relative.size() - head.size() - tail.size());
  return middle.find('/') == std::string::npos;
}

void OutputFolderOptions::Check() const {
  RequireOption(!command.empty(), "OutputFolderOptions.command", "a command name");
  for (const std::string& name : outputs) {
    RequireOption(!name.empty() && !name.starts_with('/') && name.find("..") == std::string::npos &&
                      !name.starts_with(".areomap-"),
                  "OutputFolderOptions.outputs",
                  "names relative to the output folder, without '..', not areomap's own dot files");
  }
}

OutputFolder::OutputFolder(fs::path dir, OutputFolderOptions options)
    : final_dir_(Normal(dir)), options_(std::move(options)) {
  options_.Check();
  std::error_code ec;
  const bool exists = fs::exists(final_dir_, ec);
  if (exists && !fs::is_directory(final_dir_, ec)) {
    throw Error(Quote(dir) +
                ": --out names a file that is not a folder; expected an output folder");
  }
  CheckInputs();
  if (exists) {
    const fs::path manifest = final_dir_ / kManifestName;
    if (fs::exists(manifest, ec)) {
      std::ifstream in(manifest);
      const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
      const nlohmann::json* files = j.is_object() && j.contains("files") ? &j["files"] : nullptr;
      if (files == nullptr || !files->is_object()) {
        throw Error(manifest.string() +
                    ": not an areomap output record (expected a JSON object with \"files\"); "
                    "remove it, or choose another --out");
      }
      for (const auto& [name, owner] : files->items()) {
        if (owner.is_string()) manifest_[name] = owner.get<std::string>();
      }
    } else {
      AdoptEarlierVersionsOutputs();
    }
  }
  created_ = !exists;
  fs::create_directories(final_dir_, ec);
  if (ec || !fs::is_directory(final_dir_)) {
    throw Error(dir.string() + ": cannot create output folder" +
                (ec ? ": " + ec.message() : std::string()));
  }
  if (::access(final_dir_.c_str(), W_OK) != 0) {
    throw Error(dir.string() + ": output folder is not writable");
  }
  try {
    Lock();
    CheckCollisions();
    if (options_.in_place) {
      // The folders are this command's from now on: a run killed before Commit() is resumed by
      // the next one (its units are files there), not refused as foreign.
      bool claimed = false;
      for (const std::string& pattern : options_.outputs) {
        if (pattern.ends_with('/') && !manifest_.contains(pattern)) {
          manifest_[pattern] = options_.command;
          claimed = true;
        }
      }
      if (claimed) WriteManifest();
    }
    RemoveLeftovers();
    if (options_.in_place) {
      write_dir_ = final_dir_;
    } else {
      staging_dir_ = final_dir_ / (kStagingPrefix + std::to_string(::getpid()));
      fs::create_directory(staging_dir_, ec);
      if (ec) {
        throw Error(staging_dir_.string() + ": cannot create the staging folder: " + ec.message());
      }
      write_dir_ = staging_dir_;
    }
    ArmSignalCleanup(staging_dir_, final_dir_ / kLockName, created_ ? final_dir_ : fs::path());
  } catch (...) {
    Unlock();
    if (created_) {
      fs::remove(final_dir_ / kManifestName, ec);
      fs::remove(final_dir_, ec);  // Only when empty.
    }
    throw;
  }
}

OutputFolder::~OutputFolder() {
  DisarmSignalCleanup();
  std::error_code ec;
  if (!staging_dir_.empty()) fs::remove_all(staging_dir_, ec);
  Unlock();
  if (!committed_ && created_) {
    // A folder this object made that holds nothing but the record of its own claims.
    bool only_record = true;
    for (const auto& entry : fs::directory_iterator(final_dir_, ec)) {
      only_record = only_record && entry.path().filename() == kManifestName;
    }
    if (only_record) {
      fs::remove(final_dir_ / kManifestName, ec);
      fs::remove(final_dir_, ec);
    }
  }
}

void OutputFolder::AdoptEarlierVersionsOutputs() {
  // An areomap from before the record wrote only summary.json naming the command.
  std::ifstream in(final_dir_ / "summary.json");
  if (!in) return;
  const nlohmann::json summary = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!summary.is_object() || summary.value("command", nlohmann::json()) != options_.command) {
    return;
  }
  std::error_code ec;
  for (const std::string& pattern : options_.outputs) {
    if (pattern.find('*') != std::string::npos) continue;  // Only names it surely wrote.
    const std::string name =
        pattern.ends_with('/') ? pattern.substr(0, pattern.size() - 1) : pattern;
    if (fs::exists(fs::symlink_status(final_dir_ / name, ec)))
      manifest_[pattern] = options_.command;
  }
}

void OutputFolder::Lock() {
  const fs::path path = final_dir_ / kLockName;
  for (int attempt = 0; attempt < 10; ++attempt) {
    const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) throw Error(path.string() + ": cannot open the lock file: " + std::strerror(errno));
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      char buffer[32] = {};
      const ssize_t n = ::pread(fd, buffer, sizeof(buffer) - 1, 0);
      ::close(fd);
      const std::string pid = n > 0 ? std::string(buffer, static_cast<size_t>(n)) : "?";
      throw Error(final_dir_.string() + ": another areomap process (pid " +
                  pid.substr(0, pid.find_first_of(" \n")) +
                  ") is writing into this output folder; wait for it to finish or choose another "
                  "--out");
    }
    // The holder before us may have removed the file after we opened it: lock the file that is
    // there now (a lock on a removed file protects nothing).
    struct stat held {
    }, current{};
    if (::fstat(fd, &held) == 0 && ::stat(path.c_str(), &current) == 0 &&
        held.st_ino == current.st_ino && held.st_dev == current.st_dev) {
      const std::string pid = std::to_string(::getpid()) + "\n";
      if (::ftruncate(fd, 0) != 0 || ::pwrite(fd, pid.data(), pid.size(), 0) < 0) {
        // The pid is only reported to a waiting process; the lock itself holds.
      }
      lock_fd_ = fd;
      return;
    }
    ::close(fd);
  }
  throw Error(path.string() + ": cannot take the lock (the file keeps being replaced)");
}

void OutputFolder::Unlock() {
  if (lock_fd_ < 0) return;
  ::unlink((final_dir_ / kLockName).c_str());  // While still held: no one else's lock goes.
  ::close(lock_fd_);
  lock_fd_ = -1;
}

void OutputFolder::CheckInputs() const {
  for (const fs::path& input : options_.inputs) {
    if (input.empty()) continue;
    const fs::path p = Normal(input);
    if (IsWithin(final_dir_, p)) {
      throw Error(Quote(final_dir_) + ": the output folder " +
                  (p == final_dir_ ? std::string("is the input ") : "lies inside the input ") +
                  Quote(input) + "; choose an --out outside the command's inputs");
    }
    if (!IsWithin(p, final_dir_)) continue;
    const std::string relative = Relative(p, final_dir_);
    for (const std::string& pattern : options_.outputs) {
      if (OutputNameMatches(relative, pattern)) {
        throw Error(Quote(input) + ": this input is in --out " + Quote(final_dir_) +
                    " under a name `" + options_.command + "` writes (" + pattern +
                    "); move it, or choose another --out");
      }
    }
  }
}

bool OutputFolder::OwnedByAreomap(const std::string& relative) const {
  for (const auto& [name, owner] : manifest_) {
    // A recorded file or folder, or a folder that holds recorded files.
    if (OutputNameMatches(relative, name) || name.starts_with(relative + "/")) return true;
  }
  return false;
}

void OutputFolder::CheckCollisions() const {
  std::error_code ec;
  const fs::path mission = final_dir_ / "mission.json";
  const bool writes_missions = std::find(options_.outputs.begin(), options_.outputs.end(),
                                         "mission.json") != options_.outputs.end();
  if (!writes_missions && fs::exists(mission, ec)) {
    throw Error(Quote(final_dir_) + ": this is a mission folder (it holds mission.json); `" +
                options_.command + "` does not write into a mission folder: choose another --out");
  }
  for (const std::string& pattern : options_.outputs) {
    if (!pattern.ends_with('/')) continue;
    const fs::path folder = final_dir_ / pattern.substr(0, pattern.size() - 1);
    if (fs::exists(fs::symlink_status(folder, ec)) && !fs::is_directory(folder, ec)) {
      throw Error(Quote(folder) + ": `" + options_.command +
                  "` writes a folder of this name and this is not a folder; move it away or "
                  "choose another --out");
    }
  }
  if (options_.overwrite) return;
  // Top-level entries, and the entries of nested output names' folders.
  std::vector<fs::path> folders = {final_dir_};
  for (const std::string& pattern : options_.outputs) {
    const fs::path parent = fs::path(pattern).parent_path();
    if (!parent.empty() && !pattern.ends_with('/')) folders.push_back(final_dir_ / parent);
  }
  for (const fs::path& folder : folders) {
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
      std::string relative = Relative(entry.path(), final_dir_);
      if (relative.starts_with(".areomap-") || IsAtomicTemp(entry.path().filename().string()))
        continue;
      // Fixed names only: which names a pattern ("cc_surface_*.png") takes is known once the
      // files are written, and Commit() checks those before it moves any.
      const bool output =
          std::any_of(options_.outputs.begin(), options_.outputs.end(), [&](const std::string& p) {
            return p.find('*') == std::string::npos &&
                   (OutputNameMatches(relative, p) || OutputNameMatches(relative + "/", p));
          });
      if (!output) continue;
      if (OwnedByAreomap(relative) || OwnedByAreomap(relative + "/")) continue;
      throw Error(Quote(entry.path()) + ": `" + options_.command + "` writes " +
                  (entry.is_directory() ? "a folder" : "a file") +
                  " of this name and this one is not an areomap output recorded in " +
                  Quote(final_dir_ / kManifestName) +
                  "; move it away, choose another --out, or pass --overwrite to replace it");
    }
  }
}

void OutputFolder::RemoveLeftovers() const {
  std::error_code ec;
  std::vector<fs::path> folders = {final_dir_};
  for (const auto& [name, owner] : manifest_) {
    if (name.ends_with('/')) folders.push_back(final_dir_ / name.substr(0, name.size() - 1));
  }
  for (const fs::path& folder : folders) {
    const bool recursive = folder != final_dir_;
    auto remove_if_left = [&](const fs::directory_entry& entry) {
      const std::string name = entry.path().filename().string();
      if (folder == final_dir_ && name.starts_with(kStagingPrefix) && entry.is_directory()) {
        fs::remove_all(entry.path(), ec);
      } else if (IsAtomicTemp(name) && entry.is_regular_file()) {
        fs::remove(entry.path(), ec);
      }
    };
    if (recursive) {
      for (const auto& entry : fs::recursive_directory_iterator(folder, ec)) remove_if_left(entry);
    } else {
      for (const auto& entry : fs::directory_iterator(folder, ec)) remove_if_left(entry);
    }
  }
}

void OutputFolder::Commit() {
  if (committed_) throw Error(final_dir_.string() + ": output folder committed twice");
  std::error_code ec;
  std::vector<std::string> written;
  if (!options_.in_place) {
    for (const auto& entry : fs::recursive_directory_iterator(staging_dir_, ec)) {
      if (!entry.is_directory()) written.push_back(Relative(entry.path(), staging_dir_));
    }
    if (ec)
      throw Error(staging_dir_.string() + ": cannot list the staged outputs: " + ec.message());
    std::sort(written.begin(), written.end());
    // Every check first: either all files move in, or none.
    for (const std::string& name : written) {
      const fs::path target = final_dir_ / name;
      if (!fs::exists(fs::symlink_status(target, ec))) continue;
      if (fs::is_directory(target, ec)) {
        throw Error(Quote(target) + ": a folder is where `" + options_.command +
                    "` writes a file; move it away or choose another --out");
      }
      if (!options_.overwrite && !OwnedByAreomap(name)) {
        throw Error(Quote(target) + ": `" + options_.command +
                    "` writes a file of this name and this one is not an areomap output; move "
                    "it away, choose another --out, or pass --overwrite to replace it");
      }
    }
    for (const std::string& name : written) {
      const fs::path target = final_dir_ / name;
      fs::create_directories(target.parent_path(), ec);
      fs::rename(staging_dir_ / name, target, ec);
      if (ec)
        throw Error(target.string() +
                    ": cannot move the finished file into place: " + ec.message());
    }
  } else {
    for (const std::string& pattern : options_.outputs) {
      if (pattern.find('*') != std::string::npos) continue;
      const std::string name =
          pattern.ends_with('/') ? pattern.substr(0, pattern.size() - 1) : pattern;
      if (fs::exists(final_dir_ / name, ec)) written.push_back(pattern);
    }
  }
  // This command's earlier outputs that this run did not write again: stale beside its summary.
  for (auto it = manifest_.begin(); it != manifest_.end();) {
    const bool again = std::find(written.begin(), written.end(), it->first) != written.end();
    if (it->second == options_.command && !again && !it->first.ends_with('/')) {
      const fs::path stale = final_dir_ / it->first;
      if (fs::is_regular_file(fs::symlink_status(stale, ec))) {
        fs::remove(stale, ec);
        if (ec) throw Error(stale.string() + ": cannot remove this stale output: " + ec.message());
      }
      it = manifest_.erase(it);
    } else {
      ++it;
    }
  }
  for (const std::string& name : written) manifest_[name] = options_.command;
  WriteManifest();
  committed_ = true;
}

void OutputFolder::WriteManifest() const {
  nlohmann::json files = nlohmann::json::object();
  for (const auto& [name, owner] : manifest_) files[name] = owner;
  WriteFileAtomically(final_dir_ / kManifestName,
                      nlohmann::json{{"written_by", "areomap"}, {"files", files}}.dump(2) + "\n");
}

}  // namespace areomap
