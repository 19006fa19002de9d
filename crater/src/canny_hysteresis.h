// Canny's non-maximum suppression and hysteresis on float gradients, internal to the crater
// module (DetectImageEdges, rim_edges.cc), and the edge map values it shares with the
// sub-pixel edge collection.
//
// Frame: the gradients' pixels; the map has a 1 px frame of zeros. Failure: none (a map
// without edges gives 0).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include <opencv2/core.hpp>

namespace areomap::internal {

// Edge maps: kEdge marks an edge; Canny's maps also hold kCandidate (below) and 0.
constexpr uchar kCandidate = 1;
constexpr uchar kEdge = 2;

// Calls f(c) for each c in [begin, end) with row[c] == kEdge, in increasing order; row values
// are 0, kCandidate or kEdge. Edges are sparse: words of 8 pixels without one are skipped.
template <class F>
void ForEachEdge(const uchar* row, int begin, int end, F&& f) {
  constexpr uint64_t kEdgeBits = 0x0202020202020202ull;  // kEdge's bit in each byte
  int c = begin;
  while (c < end) {
    if (c + 8 <= end) {
      uint64_t word;
      std::memcpy(&word, row + c, sizeof(word));
      if ((word & kEdgeBits) == 0) {
        c += 8;
        continue;
      }
    }
    const int stop = std::min(end, c + 8);
    for (; c < stop; ++c) {
      if (row[c] == kEdge) f(c);
    }
  }
}

// Canny's non-maximum suppression and hysteresis, as cv::Canny computes them from 16-bit
// gradients (`gx`, `gy` x `scale`, rounded as ToInt16) with the L2 norm (OpenCV 4.x canny.cpp;
// the same edges): a pixel is a candidate when its squared magnitude dx^2 + dy^2 exceeds `low`
// and is a maximum across its gradient direction, quantised to 0, 45, 90 or 135 degrees at the
// tan(22.5 degree) boundaries in OpenCV's fixed point (along the axes: above the neighbour
// behind, at least the one ahead; along a diagonal: above both), with magnitude 0 outside the
// raster; candidates 8-connected through candidates to one above `high` are edges. Written here
// so that the 16-bit gradients are made row by row (no full-size copies) and the suppression
// runs branch-free (vectorised); cv::Canny spends most of its time in data-dependent branches.
// `map`: (rows + 2) x (cols + 2) CV_8U, pixel (r, c) at (r + 1, c + 1) inside a frame of zeros;
// on return kEdge marks the edges. Returns the number of edges.
size_t NonMaximumHysteresis(const cv::Mat& gx, const cv::Mat& gy, float scale, int low, int high,
                            cv::Mat* map);

}  // namespace areomap::internal
