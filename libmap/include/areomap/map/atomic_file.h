// Writing outputs atomically: write to a temporary name in the destination folder, then rename.
// A failure (exception, crash) never leaves a half-written file under the final name.
#pragma once

#include <filesystem>
#include <string_view>

namespace areomap {

class AtomicFile {
 public:
  // Throws areomap::Error if the destination folder does not exist or is not writable.
  explicit AtomicFile(std::filesystem::path final_path);
  ~AtomicFile();  // Removes the temporary file unless Commit() succeeded.
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  // Where to write. Same folder and extension as the final path (drivers that pick a format
  // from the extension still work).
  const std::filesystem::path& temp_path() const { return temp_path_; }
  const std::filesystem::path& final_path() const { return final_path_; }
  // Renames the temporary file onto the final path. Throws areomap::Error on failure.
  void Commit();

 private:
  std::filesystem::path final_path_;
  std::filesystem::path temp_path_;
  bool committed_ = false;
};

// Writes `content` to `path` atomically. Throws areomap::Error naming the path on failure.
void WriteFileAtomically(const std::filesystem::path& path, std::string_view content);

}  // namespace areomap
