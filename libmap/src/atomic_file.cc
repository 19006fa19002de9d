#include "areomap/map/atomic_file.h"

#include <fstream>
#include <system_error>

#include <unistd.h>

#include "areomap/map/error.h"

namespace areomap {

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
}

AtomicFile::~AtomicFile() {
  if (!committed_) {
    std::error_code ignored;
    std::filesystem::remove(temp_path_, ignored);
  }
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
