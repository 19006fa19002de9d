#include "areomap/map/dtm_gridding.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/error.h"
#include "areomap/map/report_progress.h"

namespace areomap {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<uint32_t, Kernel>;
using Tds = CGAL::Triangulation_data_structure_2<VertexBase>;
using Delaunay = CGAL::Delaunay_triangulation_2<Kernel, Tds>;
using Point2 = Kernel::Point_2;

constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
// gdal_grid's test for a point on the node (alg/gdalgrid.cpp: dfR2 < 0.0000000000001).
constexpr double kCoincidentSquared = 1e-13;

// Points bucketed by cell of a grid extended by `margin` cells on every side (counting sort).
struct Buckets {
  int margin = 0;
  int width = 0;  // Extended grid.
  int height = 0;
  std::vector<uint32_t> offsets;  // Per extended cell, into `order`; size width * height + 1.
  std::vector<uint32_t> order;    // Point indices sorted by cell.

  int Index(int col, int row) const { return (row + margin) * width + (col + margin); }
  std::pair<const uint32_t*, const uint32_t*> Cell(int col, int row) const {
    const int i = Index(col, row);
    return {order.data() + offsets[i], order.data() + offsets[i + 1]};
  }
};

Buckets Bucket(const std::vector<GridPoint>& points, const GridSpec& grid, int margin) {
  Buckets b;
  b.margin = margin;
  b.width = grid.width + 2 * margin;
  b.height = grid.height + 2 * margin;
  const size_t cells = static_cast<size_t>(b.width) * static_cast<size_t>(b.height);
  std::vector<int64_t> cell_of(points.size(), -1);
  tbb::parallel_for(size_t{0}, points.size(), [&](size_t i) {
    const double col = std::floor((points[i].xyz.x() - grid.x_left) / grid.posting) + margin;
    const double row = std::floor((grid.y_top - points[i].xyz.y()) / grid.posting) + margin;
    if (col >= 0 && row >= 0 && col < b.width && row < b.height) {
      cell_of[i] = static_cast<int64_t>(row) * b.width + static_cast<int64_t>(col);
    }
  });
  b.offsets.assign(cells + 1, 0);
  for (const int64_t c : cell_of) {
    if (c >= 0) ++b.offsets[static_cast<size_t>(c) + 1];
  }
  for (size_t c = 0; c < cells; ++c) b.offsets[c + 1] += b.offsets[c];
  b.order.resize(b.offsets[cells]);
  std::vector<uint32_t> cursor(b.offsets.begin(), b.offsets.end() - 1);
  for (size_t i = 0; i < points.size(); ++i) {
    if (cell_of[i] >= 0)
      b.order[cursor[static_cast<size_t>(cell_of[i])]++] = static_cast<uint32_t>(i);
  }
  return b;
}

// Per cell, sum(w_i^2 C_i) of the points behind its elevation (upper triangle of the 3x3), so the
// sigma layer can be finished once the terrain's slope is known.
class CovarianceSums {
 public:
  CovarianceSums(const GridSpec& grid, bool enabled)
      : width_(grid.width), sums_(enabled ? static_cast<size_t>(grid.width) * grid.height : 0) {}
  bool enabled() const { return !sums_.empty(); }
  // Each cell is written by one thread only.
  void Add(int col, int row, double w, const Eigen::Matrix3d& c) {
    if (sums_.empty()) return;
    std::array<float, 6>& s = sums_[static_cast<size_t>(row) * width_ + col];
    const double w2 = w * w;
    s[0] += static_cast<float>(w2 * c(0, 0));
    s[1] += static_cast<float>(w2 * c(0, 1));
    s[2] += static_cast<float>(w2 * c(0, 2));
    s[3] += static_cast<float>(w2 * c(1, 1));
    s[4] += static_cast<float>(w2 * c(1, 2));
    s[5] += static_cast<float>(w2 * c(2, 2));
  }
  // Variance of the height at fixed (x, y) on a surface of gradient g: a^T S a, a = (-g, 1).
  double HeightVariance(int col, int row, const Eigen::Vector2d& g) const {
    const std::array<float, 6>& s = sums_[static_cast<size_t>(row) * width_ + col];
    const double ax = -g.x(), ay = -g.y();
    return ax * ax * s[0] + 2.0 * ax * ay * s[1] + 2.0 * ax * s[2] + ay * ay * s[3] +
           2.0 * ay * s[4] + s[5];
  }

 private:
  size_t width_;
  std::vector<std::array<float, 6>> sums_;
};

// Count, standard deviation and (for mean/max) elevation from the points in each cell.
void BinCells(const std::vector<GridPoint>& points, const Buckets& buckets,
              const GriddingOptions& options, GriddedLayers& out, CovarianceSums& sums) {
  const bool binned_elevation =
      options.method == GriddingMethod::kMean || options.method == GriddingMethod::kMax;
  tbb::parallel_for(0, out.grid.height, [&](int row) {
    for (int col = 0; col < out.grid.width; ++col) {
      const auto [begin, end] = buckets.Cell(col, row);
      const int n = static_cast<int>(end - begin);
      out.count.at<int32_t>(row, col) = n;
      if (n == 0) continue;
      double sum = 0.0, best = -std::numeric_limits<double>::infinity();
      uint32_t best_index = *begin;
      for (const uint32_t* it = begin; it != end; ++it) {
        const GridPoint& p = points[*it];
        sum += p.xyz.z();
        if (p.xyz.z() > best) {
          best = p.xyz.z();
          best_index = *it;
        }
      }
      const double mean = sum / n;
      if (n >= 2) {
        double squares = 0.0;
        for (const uint32_t* it = begin; it != end; ++it) {
          squares += (points[*it].xyz.z() - mean) * (points[*it].xyz.z() - mean);
        }
        out.stddev.at<float>(row, col) = static_cast<float>(std::sqrt(squares / (n - 1)));
      }
      if (!binned_elevation) continue;
      const bool use_max = options.method == GriddingMethod::kMax;
      out.elevation.at<float>(row, col) = static_cast<float>(use_max ? best : mean);
      if (use_max) {
        sums.Add(col, row, 1.0, points[best_index].covariance);
      } else {
        for (const uint32_t* it = begin; it != end; ++it) {
          sums.Add(col, row, 1.0 / n, points[*it].covariance);
        }
      }
    }
  });
}

// A cell centre on an edge belongs to exactly one of the two triangles sharing it: the one that
// runs the edge "downward" (or leftward when horizontal). Orientation is CGAL's exact predicate,
// so both triangles see the same answer.
bool Inside(const Point2& a, const Point2& b, const Point2& p) {
  const CGAL::Orientation o = CGAL::orientation(a, b, p);
  if (o == CGAL::LEFT_TURN) return true;
  if (o == CGAL::RIGHT_TURN) return false;
  return a.y() > b.y() || (a.y() == b.y() && a.x() < b.x());
}

void InterpolateTin(const std::vector<GridPoint>& points, const GriddingOptions& options,
                    const ProgressCallback& progress, GriddedLayers& out, CovarianceSums& sums) {
  std::vector<std::pair<Point2, uint32_t>> sites;
  sites.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    sites.emplace_back(Point2(points[i].xyz.x(), points[i].xyz.y()), static_cast<uint32_t>(i));
  }
  const Delaunay triangulation(sites.begin(), sites.end());
  ReportProgress(progress, 0.5, "DTM: triangles");
  std::vector<std::array<uint32_t, 3>> faces;
  faces.reserve(2 * triangulation.number_of_vertices());
  for (const auto face : triangulation.finite_face_handles()) {
    std::array<uint32_t, 3> f{face->vertex(0)->info(), face->vertex(1)->info(),
                              face->vertex(2)->info()};
    const Eigen::Vector2d centroid =
        (points[f[0]].xyz + points[f[1]].xyz + points[f[2]].xyz).head<2>() / 3.0;
    const double max_edge = std::max(
        options.max_edge_m, options.max_edge_per_range * (centroid - options.viewpoint).norm());
    const double max_edge2 = max_edge * max_edge;
    bool short_edges = true;
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector2d d = points[f[k]].xyz.head<2>() - points[f[(k + 1) % 3]].xyz.head<2>();
      short_edges = short_edges && d.squaredNorm() <= max_edge2;
    }
    if (short_edges) faces.push_back(f);
  }
  const GridSpec& g = out.grid;
  tbb::parallel_for(size_t{0}, faces.size(), [&](size_t i) {
    const std::array<uint32_t, 3>& f = faces[i];
    const Eigen::Vector3d& p0 = points[f[0]].xyz;
    const Eigen::Vector3d& p1 = points[f[1]].xyz;
    const Eigen::Vector3d& p2 = points[f[2]].xyz;
    const Point2 a(p0.x(), p0.y()), b(p1.x(), p1.y()), c(p2.x(), p2.y());
    const double min_x = std::min({p0.x(), p1.x(), p2.x()});
    const double max_x = std::max({p0.x(), p1.x(), p2.x()});
    const double min_y = std::min({p0.y(), p1.y(), p2.y()});
    const double max_y = std::max({p0.y(), p1.y(), p2.y()});
    // Cells whose centres the triangle's bounding box holds (clamped before any cast).
    const auto cell = [](double v, int hi) {
      return static_cast<int>(std::clamp(v, -1.0, hi + 1.0));
    };
    const int col0 = std::max(0, cell(std::ceil((min_x - g.x_left) / g.posting - 0.5), g.width));
    const int col1 =
        std::min(g.width - 1, cell(std::floor((max_x - g.x_left) / g.posting - 0.5), g.width));
    const int row0 = std::max(0, cell(std::ceil((g.y_top - max_y) / g.posting - 0.5), g.height));
    const int row1 =
        std::min(g.height - 1, cell(std::floor((g.y_top - min_y) / g.posting - 0.5), g.height));
    if (col0 > col1 || row0 > row1) return;
    const Eigen::Vector2d e1 = (p1 - p0).head<2>(), e2 = (p2 - p0).head<2>();
    const double area2 = e1.x() * e2.y() - e1.y() * e2.x();  // > 0: CGAL faces are ccw.
    if (!(area2 > 0.0)) return;
    for (int row = row0; row <= row1; ++row) {
      for (int col = col0; col <= col1; ++col) {
        const Eigen::Vector2d center = g.CellCenter(col, row);
        const Point2 p(center.x(), center.y());
        if (!Inside(a, b, p) || !Inside(b, c, p) || !Inside(c, a, p)) continue;
        const Eigen::Vector2d d = center - p0.head<2>();
        const double w1 = (d.x() * e2.y() - d.y() * e2.x()) / area2;
        const double w2 = (e1.x() * d.y() - e1.y() * d.x()) / area2;
        const double w0 = 1.0 - w1 - w2;
        out.elevation.at<float>(row, col) =
            static_cast<float>(w0 * p0.z() + w1 * p1.z() + w2 * p2.z());
        sums.Add(col, row, w0, points[f[0]].covariance);
        sums.Add(col, row, w1, points[f[1]].covariance);
        sums.Add(col, row, w2, points[f[2]].covariance);
      }
    }
  });
}

void InterpolateInverseDistance(const std::vector<GridPoint>& points, const Buckets& buckets,
                                const GriddingOptions& options, GriddedLayers& out,
                                CovarianceSums& sums) {
  const GridSpec& g = out.grid;
  const double radius2 = options.idw_radius_m * options.idw_radius_m;
  const int reach = buckets.margin;
  const bool square_power = options.idw_power == 2.0;
  const size_t max_points = static_cast<size_t>(options.idw_max_points);
  tbb::enumerable_thread_specific<std::vector<std::pair<double, uint32_t>>> scratch;
  tbb::parallel_for(0, g.height, [&](int row) {
    std::vector<std::pair<double, uint32_t>>& near = scratch.local();
    for (int col = 0; col < g.width; ++col) {
      const Eigen::Vector2d center = g.CellCenter(col, row);
      near.clear();
      // Rings of buckets outward; stop once the k-th nearest is nearer than the next ring.
      for (int ring = 0; ring <= reach; ++ring) {
        for (int r = row - ring; r <= row + ring; ++r) {
          const bool full_row = ring == 0 || r == row - ring || r == row + ring;
          for (int c = col - ring; c <= col + ring; c += full_row ? 1 : 2 * ring) {
            // Skip buckets wholly outside the radius (their nearest point to the centre).
            const double gap_x = std::max(0, std::abs(c - col) - 1) * g.posting;
            const double gap_y = std::max(0, std::abs(r - row) - 1) * g.posting;
            if (gap_x * gap_x + gap_y * gap_y > radius2) continue;
            const auto [begin, end] = buckets.Cell(c, r);
            for (const uint32_t* it = begin; it != end; ++it) {
              const double d2 = (points[*it].xyz.head<2>() - center).squaredNorm();
              if (d2 <= radius2) near.emplace_back(d2, *it);
            }
          }
        }
        if (near.size() >= max_points) {
          std::nth_element(near.begin(), near.begin() + (max_points - 1), near.end());
          const double beyond = (ring + 0.5) * g.posting;
          if (near[max_points - 1].first <= beyond * beyond) break;
        }
      }
      if (near.empty()) continue;
      if (static_cast<int>(near.size()) > options.idw_max_points) {
        std::nth_element(near.begin(), near.begin() + options.idw_max_points, near.end());
        near.resize(static_cast<size_t>(options.idw_max_points));
      }
      const auto nearest = std::min_element(near.begin(), near.end());
      if (nearest->first < kCoincidentSquared) {
        const GridPoint& p = points[nearest->second];
        out.elevation.at<float>(row, col) = static_cast<float>(p.xyz.z());
        sums.Add(col, row, 1.0, p.covariance);
        continue;
      }
      double weights = 0.0, weighted = 0.0;
      for (auto& [d2, index] : near) {
        d2 = square_power ? 1.0 / d2 : std::pow(d2, -0.5 * options.idw_power);  // Now w.
        weights += d2;
        weighted += d2 * points[index].xyz.z();
      }
      out.elevation.at<float>(row, col) = static_cast<float>(weighted / weights);
      for (const auto& [w, index] : near) sums.Add(col, row, w / weights, points[index].covariance);
    }
  });
}

// sigma = sqrt(a^T S a) with the gradient of the elevation smoothed over `slope_baseline_m`
// (a single triangle's gradient is dominated by the points' own noise where they are dense).
void FinishSigma(const CovarianceSums& sums, const GriddingOptions& options, GriddedLayers& out) {
  if (!sums.enabled()) return;
  const GridSpec& g = out.grid;
  cv::Mat known(g.height, g.width, CV_32F), filled(g.height, g.width, CV_32F);
  for (int row = 0; row < g.height; ++row) {
    for (int col = 0; col < g.width; ++col) {
      const float z = out.elevation.at<float>(row, col);
      known.at<float>(row, col) = std::isfinite(z) ? 1.0f : 0.0f;
      filled.at<float>(row, col) = std::isfinite(z) ? z : 0.0f;
    }
  }
  const int half =
      std::max(1, static_cast<int>(std::lround(0.5 * options.slope_baseline_m / g.posting)));
  const cv::Size window(2 * half + 1, 2 * half + 1);
  cv::Mat sum_z, sum_known;
  cv::boxFilter(filled, sum_z, CV_32F, window, cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
  cv::boxFilter(known, sum_known, CV_32F, window, cv::Point(-1, -1), false, cv::BORDER_CONSTANT);
  const auto smoothed = [&](int col, int row) -> double {
    if (col < 0 || row < 0 || col >= g.width || row >= g.height) return NAN;
    const float n = sum_known.at<float>(row, col);
    return n > 0.5f ? sum_z.at<float>(row, col) / n : NAN;
  };
  tbb::parallel_for(0, g.height, [&](int row) {
    for (int col = 0; col < g.width; ++col) {
      if (!std::isfinite(out.elevation.at<float>(row, col))) continue;
      // Central differences of the smoothed surface over the baseline; 0 where unknown.
      const auto slope = [&](double lo, double hi) {
        const double d = (hi - lo) / (2.0 * half * g.posting);
        return std::isfinite(d) ? d : 0.0;
      };
      const Eigen::Vector2d gradient(slope(smoothed(col - half, row), smoothed(col + half, row)),
                                     slope(smoothed(col, row + half), smoothed(col, row - half)));
      out.sigma.at<float>(row, col) =
          static_cast<float>(std::sqrt(std::max(0.0, sums.HeightVariance(col, row, gradient))));
    }
  });
}

}  // namespace

std::string ToString(GriddingMethod method) {
  switch (method) {
    case GriddingMethod::kTin:
      return "tin";
    case GriddingMethod::kMean:
      return "mean";
    case GriddingMethod::kMax:
      return "max";
    case GriddingMethod::kInverseDistance:
      return "idw";
  }
  return "?";
}

GriddingMethod GriddingMethodFromString(std::string_view text) {
  for (const GriddingMethod m : {GriddingMethod::kTin, GriddingMethod::kMean, GriddingMethod::kMax,
                                 GriddingMethod::kInverseDistance}) {
    if (text == ToString(m)) return m;
  }
  throw Error("unknown gridding method '" + std::string(text) +
              "': expected tin, mean, max or idw");
}

GridSpec GridSpec::Covering(const Eigen::Vector2d& min, const Eigen::Vector2d& max,
                            double posting) {
  RequireOption(posting > 0.0 && std::isfinite(posting), "GridSpec.posting", "a positive size [m]");
  if (!min.allFinite() || !max.allFinite() || (max - min).minCoeff() < 0.0) {
    throw Error("DTM grid: the point bounds are empty or not finite");
  }
  GridSpec g;
  g.posting = posting;
  g.x_left = std::floor(min.x() / posting) * posting;
  g.y_top = (std::floor(max.y() / posting) + 1.0) * posting;
  const double width = std::floor(max.x() / posting) - std::floor(min.x() / posting) + 1.0;
  const double height = std::floor(max.y() / posting) - std::floor(min.y() / posting) + 1.0;
  if (!(width * height <= 4e8)) {
    char text[200];
    std::snprintf(text, sizeof(text),
                  "DTM posting %g m is too fine for the points' extent of %.0f x %.0f m: %.3g "
                  "cells, more than 4e8; expected a coarser posting",
                  posting, max.x() - min.x(), max.y() - min.y(), width * height);
    throw Error(text);
  }
  g.width = static_cast<int>(width);
  g.height = static_cast<int>(height);
  g.Check();
  return g;
}

GeoTransform GridSpec::Transform() const {
  return GeoTransform::NorthUp(x_left, y_top, posting, posting);
}

std::optional<GridSpec> GridSpec::Window(const Eigen::Vector2d& min,
                                         const Eigen::Vector2d& max) const {
  const double col0 = std::max(0.0, std::floor((min.x() - x_left) / posting));
  const double col1 = std::min(width - 1.0, std::floor((max.x() - x_left) / posting));
  const double row0 = std::max(0.0, std::floor((y_top - max.y()) / posting));
  const double row1 = std::min(height - 1.0, std::floor((y_top - min.y()) / posting));
  if (!(col0 <= col1 && row0 <= row1)) return std::nullopt;
  GridSpec window = *this;
  window.x_left = x_left + col0 * posting;
  window.y_top = y_top - row0 * posting;
  window.width = static_cast<int>(col1 - col0) + 1;
  window.height = static_cast<int>(row1 - row0) + 1;
  return window;
}

Eigen::Vector2i GridSpec::OffsetIn(const GridSpec& parent) const {
  const double col = (x_left - parent.x_left) / parent.posting;
  const double row = (parent.y_top - y_top) / parent.posting;
  const Eigen::Vector2i offset(static_cast<int>(std::lround(col)),
                               static_cast<int>(std::lround(row)));
  if (std::abs(posting - parent.posting) > 1e-9 * parent.posting ||
      std::abs(col - offset.x()) > 1e-6 || std::abs(row - offset.y()) > 1e-6 || offset.x() < 0 ||
      offset.y() < 0 || offset.x() + width > parent.width || offset.y() + height > parent.height) {
    throw Error("grid: not a window of the common grid (posting or alignment differ)");
  }
  return offset;
}

Eigen::Vector2d GridSpec::CellCenter(int col, int row) const {
  return {x_left + (col + 0.5) * posting, y_top - (row + 0.5) * posting};
}

void GridSpec::Check() const {
  RequireOption(posting > 0.0 && std::isfinite(posting), "GridSpec.posting", "a positive size [m]");
  RequireOption(std::isfinite(x_left) && std::isfinite(y_top), "GridSpec.x_left/y_top",
                "finite map coordinates");
  RequireOption(width > 0 && height > 0 && static_cast<double>(width) * height <= 4e8,
                "GridSpec.width/height", "a positive size of at most 4e8 cells");
}

void GriddingOptions::Check() const {
  RequireOption(max_edge_m > 0.0, "GriddingOptions.max_edge_m", "a positive length [m]");
  RequireOption(max_edge_per_range >= 0.0 && max_edge_per_range < 10.0,
                "GriddingOptions.max_edge_per_range", "in [0, 10)");
  RequireOption(viewpoint.allFinite(), "GriddingOptions.viewpoint", "finite map coordinates");
  RequireOption(slope_baseline_m > 0.0, "GriddingOptions.slope_baseline_m",
                "a positive length [m]");
  RequireOption(idw_radius_m > 0.0, "GriddingOptions.idw_radius_m", "a positive radius [m]");
  RequireOption(idw_power > 0.0 && idw_power <= 8.0, "GriddingOptions.idw_power", "in (0, 8]");
  RequireOption(idw_max_points >= 1, "GriddingOptions.idw_max_points", ">= 1");
}

GriddedLayers GridPoints(const std::vector<GridPoint>& points, const GridSpec& grid,
                         const GriddingOptions& options, const ProgressCallback& progress) {
  options.Check();
  grid.Check();
  if (points.size() >= std::numeric_limits<uint32_t>::max()) {
    throw Error("DTM gridding: more than 4e9 points");
  }
  for (size_t i = 0; i < points.size(); ++i) {
    if (!points[i].xyz.allFinite() || !points[i].covariance.allFinite()) {
      throw Error("DTM gridding: point " + std::to_string(i) + " is not finite");
    }
  }
  GriddedLayers out;
  out.grid = grid;
  out.elevation = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  out.sigma = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  out.stddev = cv::Mat(grid.height, grid.width, CV_32F, cv::Scalar(kNaNf));
  out.count = cv::Mat(grid.height, grid.width, CV_32S, cv::Scalar(0));
  ReportProgress(progress, 0.0, "DTM: binning");
  RequireOption(options.idw_radius_m / grid.posting <= 1000.0, "GriddingOptions.idw_radius_m",
                "at most 1000 cells");
  const int margin = options.method == GriddingMethod::kInverseDistance
                         ? static_cast<int>(std::ceil(options.idw_radius_m / grid.posting))
                         : 0;
  const Buckets buckets = Bucket(points, grid, margin);
  CovarianceSums sums(grid, options.compute_sigma);
  BinCells(points, buckets, options, out, sums);
  ReportProgress(progress, 0.2, "DTM: interpolation");
  if (options.method == GriddingMethod::kTin && points.size() >= 3) {
    InterpolateTin(points, options, progress, out, sums);
  } else if (options.method == GriddingMethod::kInverseDistance) {
    InterpolateInverseDistance(points, buckets, options, out, sums);
  }
  ReportProgress(progress, 0.9, "DTM: sigma");
  FinishSigma(sums, options, out);
  out.known_cells = 0;
  for (int row = 0; row < grid.height; ++row) {
    for (int col = 0; col < grid.width; ++col) {
      out.known_cells += std::isfinite(out.elevation.at<float>(row, col)) ? 1 : 0;
    }
  }
  ReportProgress(progress, 1.0, "DTM: done");
  return out;
}

}  // namespace areomap
