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
  PointGrid(const std::vector<Eigen::Vector2d>& xy, double cell_m) : cell_(cell_m) {
    if (xy.empty()) return;
    lo_ = xy.front();
    Eigen::Vector2d hi = lo_;
    for (const Eigen::Vector2d& p : xy) {
      lo_ = lo_.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    nx_ = static_cast<int>(std::floor((hi.x() - lo_.x()) / cell_)) + 1;
    ny_ = static_cast<int>(std::floor((hi.y() - lo_.y()) / cell_)) + 1;
    start_.assign(static_cast<size_t>(nx_) * ny_ + 1, 0);
    std::vector<int> cell_of(xy.size());
    for (size_t i = 0; i < xy.size(); ++i) {
      cell_of[i] = Cell(CellX(xy[i].x()), CellY(xy[i].y()));
      ++start_[static_cast<size_t>(cell_of[i]) + 1];
    }
    for (size_t c = 1; c < start_.size(); ++c) start_[c] += start_[c - 1];
    order_.resize(xy.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (size_t i = 0; i < xy.size(); ++i) order_[fill[cell_of[i]]++] = static_cast<int>(i);
  }

  int nx() const { return nx_; }
  int ny() const { return ny_; }
  double cell() const { return cell_; }
  int CellX(double x) const {
    return std::clamp(static_cast<int>((x - lo_.x()) / cell_), 0, nx_ - 1);
  }
  int CellY(double y) const {
    return std::clamp(static_cast<int>((y - lo_.y()) / cell_), 0, ny_ - 1);
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
