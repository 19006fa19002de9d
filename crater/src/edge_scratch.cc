#include "edge_scratch.h"

#include <algorithm>
#include <utility>

#include "areomap/map/error.h"

namespace areomap::internal {
namespace {

thread_local EdgeScratch* current_scratch = nullptr;

}  // namespace

cv::Mat EdgeScratch::Get(int slot, int rows, int cols, int type,
                         std::optional<size_t> slot_reserve_pixels) {
  RequireOption(slot >= 0 && slot < kSlots, "EdgeScratch.slot", "in [0, kSlots)");
  const size_t bytes = static_cast<size_t>(rows) * static_cast<size_t>(cols) * CV_ELEM_SIZE(type);
  auto& memory = memory_[static_cast<size_t>(slot)];
  size_t& capacity = capacity_[static_cast<size_t>(slot)];
  if (bytes > capacity) {
    capacity = std::max(bytes, slot_reserve_pixels.value_or(reserve_pixels_) * CV_ELEM_SIZE(type));
    memory = std::make_unique_for_overwrite<unsigned char[]>(capacity);
  }
  return cv::Mat(rows, cols, type, memory.get());
}

EdgeScratch* CurrentEdgeScratch() { return current_scratch; }

UseEdgeScratch::UseEdgeScratch(EdgeScratch* scratch) : previous_(current_scratch) {
  current_scratch = scratch;
}

UseEdgeScratch::~UseEdgeScratch() { current_scratch = previous_; }

std::unique_ptr<EdgeScratch> EdgeScratchPool::Acquire() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (free_.empty()) return std::make_unique<EdgeScratch>(reserve_pixels_);
  std::unique_ptr<EdgeScratch> scratch = std::move(free_.back());
  free_.pop_back();
  return scratch;
}

void EdgeScratchPool::Release(std::unique_ptr<EdgeScratch> scratch) {
  std::lock_guard<std::mutex> lock(mutex_);
  free_.push_back(std::move(scratch));
}

}  // namespace areomap::internal
