// Reusable memory for the full-size temporaries of rim edge detection (rim_edges.h): the
// gradient magnitude, the gradients, the edge map; and for a tile as read and the detector's 2x
// upsampled copy of it (four times a tile's pixels).
// Internal to the crater module.
//
// A tiled detection (DetectCratersInRaster) hands each tile task one EdgeScratch from an
// EdgeScratchPool for the duration of the call: consecutive tiles and pyramid levels reuse the
// memory instead of allocating it afresh, each page faulted in again (in a VM about 8 us a
// page). Per pixel of a padded tile a scratch reserves 18 bytes, or 73 with the upsampled level
// (for 2304 px tiles 97 or 390 MB; the coarser levels take a third of a tile's floats); pages are
// touched only as far as used (the upsampled level's edge temporaries hold one search region or
// threshold strip at a time). Memory stays bounded by the tile size times the tiles in flight; the
// pool frees everything when it is destroyed.
//
// Thread safety: an EdgeScratch is used by one task at a time. UseEdgeScratch makes it the
// calling thread's current scratch until it goes out of scope, restoring the previous one: a
// task that TBB runs nested on the same thread (work stealing while waiting) installs its own
// scratch and restores the outer one before the outer task resumes.
#pragma once

#include <array>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

namespace areomap::internal {

class EdgeScratch {
 public:
  // Slots 0-3: rim_edges.cc's temporaries; kUpsampledImageSlot and kPyramidSlot: the
  // detector's 2x upsampled level and its coarser levels (crater_detector.cc), which live while
  // their edges are computed in the other slots; kTileSlot: the tile itself (crater_raster.cc),
  // alive for the whole detection on it.
  static constexpr int kUpsampledImageSlot = 4;
  static constexpr int kTileSlot = 5;
  static constexpr int kPyramidSlot = 6;  // the detector's coarser levels, one after the other
  static constexpr int kSlots = 7;
  // `reserve_pixels`: the largest level expected (a padded tile, or its 2x upsampled copy, plus
  // the edge map's 1 px border), so that growing happens once.
  explicit EdgeScratch(size_t reserve_pixels = 0) : reserve_pixels_(reserve_pixels) {}
  // A continuous rows x cols matrix of `type` over the memory of `slot` (grown when too small,
  // to at least reserve_pixels, or `slot_reserve_pixels` when given); its contents are
  // undefined. Valid until the next Get of the same slot, and only while the scratch is
  // acquired (a released one goes to the next tile task).
  cv::Mat Get(int slot, int rows, int cols, int type,
              std::optional<size_t> slot_reserve_pixels = std::nullopt);

 private:
  size_t reserve_pixels_;
  std::array<std::unique_ptr<unsigned char[]>, kSlots> memory_;
  std::array<size_t, kSlots> capacity_{};
};

// The calling thread's current scratch; nullptr when none is installed (callers then allocate).
EdgeScratch* CurrentEdgeScratch();

class UseEdgeScratch {
 public:
  explicit UseEdgeScratch(EdgeScratch* scratch);
  ~UseEdgeScratch();
  UseEdgeScratch(const UseEdgeScratch&) = delete;
  UseEdgeScratch& operator=(const UseEdgeScratch&) = delete;

 private:
  EdgeScratch* previous_;
};

// Scratches for the tasks of one call; Acquire reuses a released one or makes a new one.
class EdgeScratchPool {
 public:
  explicit EdgeScratchPool(size_t reserve_pixels) : reserve_pixels_(reserve_pixels) {}
  std::unique_ptr<EdgeScratch> Acquire();
  void Release(std::unique_ptr<EdgeScratch> scratch);

 private:
  size_t reserve_pixels_;
  std::mutex mutex_;
  std::vector<std::unique_ptr<EdgeScratch>> free_;
};

}  // namespace areomap::internal
