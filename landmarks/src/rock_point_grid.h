// Internal to rock extraction: a uniform grid over the horizontal (x, y) coordinates of a point
// set, stored as sorted cell runs (counting sort), for window and radius queries without
// scanning every point. Units: metres of the points' frame.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace areomap::rock_internal {

class PointGrid {
 public:
  // Indexes the points with keep[i] != 0 (all points when `keep` is null); indices refer to `xy`.
  PointGrid(const std::vector<Eigen::Vector2d>& xy, double cell_m,
            const std::vector<char>* keep = nullptr)
      : cell_(cell_m) {
    bool any = false;
    Eigen::Vector2d hi = Eigen::Vector2d::Zero();
    for (size_t i = 0; i < xy.size(); ++i) {
      if (keep && !(*keep)[i]) continue;
      lo_ = any ? lo_.cwiseMin(xy[i]) : xy[i];
      hi = any ? hi.cwiseMax(xy[i]) : xy[i];
      any = true;
    }
    if (!any) return;
    nx_ = static_cast<int>(std::floor((hi.x() - lo_.x()) / cell_)) + 1;
    ny_ = static_cast<int>(std::floor((hi.y() - lo_.y()) / cell_)) + 1;
    start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
    std::vector<int> cell_of(xy.size(), -1);
    for (size_t i = 0; i < xy.size(); ++i) {
      if (keep && !(*keep)[i]) continue;
      cell_of[i] = Cell(CellX(xy[i].x()), CellY(xy[i].y()));
      ++start_[static_cast<size_t>(cell_of[i]) + 1];
    }
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    order_.resize(static_cast<size_t>(start_.back()));
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < xy.size(); ++i) {
      if (cell_of[i] >= 0) order_[fill[cell_of[i]]++] = static_cast<int>(i);
    }
  }

  int nx() const { return nx_; }
  int ny() const { return ny_; }
  double cell() const { return cell_; }
  // Cell column / row of a coordinate, clamped to the grid (as doubles first, so that far
  // coordinates never overflow the conversion).
  int CellX(double x) const {
    return static_cast<int>(std::clamp((x - lo_.x()) / cell_, 0.0, nx_ - 1.0));
  }
  int CellY(double y) const {
    return static_cast<int>(std::clamp((y - lo_.y()) / cell_, 0.0, ny_ - 1.0));
  }
  int Cell(int cx, int cy) const { return cy * nx_ + cx; }
  // Indices of the points in cell (cx, cy).
  const int* begin(int cell) const { return order_.data() + start_[cell]; }
  const int* end(int cell) const { return order_.data() + start_[cell + 1]; }

  // Calls f(index) for every point in cells overlapping the square centre +- half.
  template <typename F>
  void ForEachNear(const Eigen::Vector2d& centre, double half, F&& f) const {
    if (nx_ == 0) return;
    const int x0 = CellX(centre.x() - half), x1 = CellX(centre.x() + half);
    const int y0 = CellY(centre.y() - half), y1 = CellY(centre.y() + half);
    for (int cy = y0; cy <= y1; ++cy) {
      for (int cx = x0; cx <= x1; ++cx) {
        const int c = Cell(cx, cy);
        for (const int* it = begin(c); it != end(c); ++it) f(*it);
      }
    }
  }

 private:
  double cell_;
  Eigen::Vector2d lo_ = Eigen::Vector2d::Zero();
  int nx_ = 0, ny_ = 0;
  std::vector<int> start_;
  std::vector<int> order_;
};

}  // namespace areomap::rock_internal
