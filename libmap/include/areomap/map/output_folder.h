// The output-folder policy of every areomap command (--out DIR), in one place.
//
// Rule: a command writes only the files it owns and never deletes a file it cannot prove it wrote.
//  - DIR/.areomap-outputs.json records which command wrote each output (a file, or "name/" for a
//    folder a command owns whole). A recorded file is areomap's and a later run may replace it; a
//    file this command recorded and did not write again is removed (a stale optional output).
//    Nothing else in DIR is ever removed or replaced. A folder an earlier areomap wrote (no record,
//    a summary.json naming this command) counts as this command's for its fixed output names.
//  - Refused before any work, naming the file and how to proceed: DIR is an input of the command
//    or lies inside one; an input inside DIR carries one of the command's output names; DIR holds
//    mission.json and the command does not write missions; an output name in DIR is held by a
//    file no areomap command recorded (a foreign file), unless `overwrite` (--overwrite); a file
//    where the command writes a folder; another process is writing into DIR (advisory lock
//    DIR/.areomap-lock by flock(2): a dead process's lock is free again; the pid is only reported).
//  - Staged commands write into a staging folder (dir()); Commit() checks every staged name, then
//    moves the files in by rename: a command that fails leaves the previous result as it was.
//    A command whose work units persist across runs (the mission run) writes in place; its
//    folders are recorded as its own when it starts, so a killed run is resumed, not refused.
//  - Temporary files a killed run left (.areomap-staging-*, AtomicFile's .tmp-<pid>-*) are removed
//    by the next run, which holds the lock; on SIGINT / SIGTERM the staging folder, the
//    AtomicFile temporaries being written and the lock are removed before the process ends with
//    the signal (SIGKILL: by the next run).
// Failure: every refusal throws areomap::Error naming the file or folder and what to do.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace areomap {

struct OutputFolderOptions {
  std::string command;  // e.g. "stereo", "rocks match": recorded as the owner of its outputs.
  // The names the command may write, relative to DIR: a file name, a pattern in which one '*' in
  // the last component stands for any run of characters ("cc_surface_*.png"), or a folder that the
  // command owns whole ("sites/").
  std::vector<std::string> outputs;
  // The files and folders the command reads (refused when one of them is an output, or holds DIR).
  std::vector<std::filesystem::path> inputs;
  bool overwrite = false;  // Replace foreign files that carry an output's name (--overwrite).
  bool in_place = false;   // Write into DIR directly (no staging folder).
  void Check() const;      // Throws areomap::Error naming the field.
};

class OutputFolder {
 public:
  // Checks DIR against the rules above, creates it if needed, takes the lock, removes temporary
  // files a killed run left, and (unless in_place) makes the staging folder.
  OutputFolder(std::filesystem::path dir, OutputFolderOptions options);
  // Without Commit(): removes the staging folder, and DIR too if this object created it and
  // nothing else is in it; releases the lock.
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  // Where the command writes: the staging folder, or DIR when in_place.
  const std::filesystem::path& dir() const { return write_dir_; }
  // The final folder (DIR).
  const std::filesystem::path& final_dir() const { return final_dir_; }
  // dir() / name.
  std::filesystem::path operator/(const std::filesystem::path& name) const {
    return write_dir_ / name;
  }

  // Moves every staged file into DIR (each by rename, after checking that none would replace a
  // foreign file), removes this command's earlier outputs that were not written again, records
  // the outputs in DIR/.areomap-outputs.json and removes the staging folder. In place: records
  // the output names that now exist in DIR. Throws areomap::Error naming the file on failure.
  void Commit();

  // The manifest's name inside DIR.
  static constexpr const char* kManifestName = ".areomap-outputs.json";
  static constexpr const char* kLockName = ".areomap-lock";

 private:
  void AdoptEarlierVersionsOutputs();
  void Lock();
  void Unlock();
  void CheckInputs() const;
  void CheckCollisions() const;
  void RemoveLeftovers() const;
  void WriteManifest() const;
  bool OwnedByAreomap(const std::string& relative) const;

  std::filesystem::path final_dir_;
  std::filesystem::path write_dir_;
  std::filesystem::path staging_dir_;  // Empty when in_place.
  OutputFolderOptions options_;
  std::map<std::string, std::string> manifest_;  // Output path (folders end in '/') -> command.
  int lock_fd_ = -1;
  bool created_ = false;
  bool committed_ = false;
};

// Whether `relative` (a path inside DIR, '/'-separated) is named by `pattern` as in
// OutputFolderOptions::outputs: equal, matching one '*', or inside a folder pattern "name/".
bool OutputNameMatches(const std::string& relative, const std::string& pattern);

}  // namespace areomap
