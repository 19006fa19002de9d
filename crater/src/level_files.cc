#include "level_files.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"

namespace areomap::internal {
namespace {

// Output rows per strip while a level is built.
constexpr int kStripRows = 256;

std::string SystemError(const std::string& what) {
  return "crater pyramid level file: " + what + ": " + std::strerror(errno);
}

// A new file in the temporary folder, already unlinked: it goes when `fd` is closed.
int MakeUnlinkedFile() {
  std::string path =
      (std::filesystem::temp_directory_path() / "areomap-crater-level-XXXXXX").string();
  const int fd = mkstemp(path.data());
  if (fd < 0) throw Error(SystemError("cannot create " + path));
  unlink(path.c_str());
  return fd;
}

// Moves all `bytes` at `offset` with pread or pwrite (`transfer`), which may move fewer at a
// time; throws with `what` when one moves none.
template <typename Buffer, typename Transfer>
void TransferAll(Transfer transfer, int fd, Buffer* data, size_t bytes, off_t offset,
                 const char* what) {
  for (size_t done = 0; done < bytes;) {
    const ssize_t n = transfer(fd, data + done, bytes - done, offset + static_cast<off_t>(done));
    if (n <= 0) throw Error(SystemError(what));
    done += static_cast<size_t>(n);
  }
}

// 2 x 2 means of `rows` (an even number of rows, at least 2 x width columns), NaN where any of
// the four is NaN.
cv::Mat HalveRows(const cv::Mat& rows, int width) {
  cv::Mat out;
  cv::resize(rows(cv::Rect(0, 0, 2 * width, rows.rows)), out, cv::Size(width, rows.rows / 2), 0, 0,
             cv::INTER_AREA);
  return out;
}

}  // namespace

PyramidLevelFiles::PyramidLevelFiles(cv::Size raster, int levels, const RasterReader& read) {
  const auto add_level = [&](int l) {
    const cv::Size size(raster.width >> l, raster.height >> l);
    if (size.width < 1 || size.height < 1 || l >= levels) return false;
    levels_.push_back(Level{MakeUnlinkedFile(), size});
    return true;
  };
  try {
    // Level 0, the raster decoded once, and level 1 from the same strips of 2 kStripRows rows (an
    // odd last row has no level-1 row).
    add_level(0);
    const bool has_level1 = add_level(1);
    const int strip_rows = 2 * kStripRows;
    // Strips in parallel: decoding a compressed raster is most of the work.
    tbb::parallel_for(0, (raster.height + strip_rows - 1) / strip_rows, [&](int k) {
      const int r0 = k * strip_rows, rows = std::min(strip_rows, raster.height - r0);
      const cv::Mat full = read(cv::Rect(0, r0, raster.width, rows));
      WriteRows(levels_[0], r0, full);
      if (has_level1 && rows >= 2) {
        WriteRows(levels_[1], r0 / 2,
                  HalveRows(full.rowRange(0, rows & ~1), levels_[1].size.width));
      }
    });
    // Each next level from the file below.
    for (int l = 2; add_level(l); ++l) {
      const Level& level = levels_[static_cast<size_t>(l)];
      const cv::Size below = levels_[static_cast<size_t>(l - 1)].size;
      tbb::parallel_for(0, (level.size.height + kStripRows - 1) / kStripRows, [&](int k) {
        const int r0 = k * kStripRows, rows = std::min(kStripRows, level.size.height - r0);
        WriteRows(
            level, r0,
            HalveRows(Read(l - 1, cv::Rect(0, 2 * r0, below.width, 2 * rows)), level.size.width));
      });
    }
  } catch (...) {
    for (const Level& level : levels_) close(level.fd);
    throw;
  }
}

PyramidLevelFiles::~PyramidLevelFiles() {
  for (const Level& level : levels_) close(level.fd);
}

void PyramidLevelFiles::WriteRows(const Level& level, int row0, const cv::Mat& rows) const {
  // A strip's rows are whole level rows, and contiguous in a continuous matrix: one write.
  const cv::Mat strip = rows.isContinuous() ? rows : rows.clone();
  const size_t row_bytes = static_cast<size_t>(level.size.width) * sizeof(float);
  TransferAll(pwrite, level.fd, reinterpret_cast<const char*>(strip.ptr<float>(0)),
              row_bytes * static_cast<size_t>(strip.rows),
              static_cast<off_t>(row0) * static_cast<off_t>(row_bytes), "cannot write");
}

cv::Mat PyramidLevelFiles::Read(int level, const cv::Rect& rect) const {
  cv::Mat out;
  ReadInto(level, rect, &out);
  return out;
}

void PyramidLevelFiles::ReadInto(int level, const cv::Rect& rect, cv::Mat* out) const {
  if (level < 0 || level >= static_cast<int>(levels_.size())) {
    throw Error("crater pyramid level file: no level " + std::to_string(level));
  }
  const Level& l = levels_[static_cast<size_t>(level)];
  if ((rect & cv::Rect(0, 0, l.size.width, l.size.height)) != rect) {
    throw Error("crater pyramid level file: window outside level " + std::to_string(level));
  }
  if (out->size() != rect.size() || out->type() != CV_32F) *out = cv::Mat(rect.size(), CV_32F);
  const size_t row_bytes = static_cast<size_t>(rect.width) * sizeof(float);
  for (int r = 0; r < rect.height; ++r) {
    const off_t at = (static_cast<off_t>(rect.y + r) * l.size.width + rect.x) *
                     static_cast<off_t>(sizeof(float));
    TransferAll(pread, l.fd, reinterpret_cast<char*>(out->ptr<float>(r)), row_bytes, at,
                "cannot read");
  }
}

}  // namespace areomap::internal
