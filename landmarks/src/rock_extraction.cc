// Rock extraction (ch. 2.2.2): peaks, robust background plane, surface points, models.
#include "areomap/landmarks/rock_extraction.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <unordered_map>
#include <unordered_set>

#include <tbb/parallel_for.h>
#include <Eigen/Eigenvalues>

#include "areomap/map/error.h"
#include "rock_point_grid.h"
#include "rock_voxel_index.h"

namespace areomap {

namespace {

using rock_internal::PointGrid;
using rock_internal::VoxelIndex;

struct Plane {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d(0, 0, -1);  // Up in the site frame (z down).
  int inliers = 0;
  double residual_sigma = 0.0;  // Robust (MAD) sigma of the inliers' distances to the plane [m].
};

// Least-squares plane through `points` (smallest principal axis), normal pointing up.
Plane FitPlane(const std::vector<Eigen::Vector3d>& points) {
  Plane plane;
  for (const Eigen::Vector3d& p : points) plane.point += p;
  plane.point /= static_cast<double>(points.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& p : points) {
    scatter += (p - plane.point) * (p - plane.point).transpose();
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
  plane.normal = eigen.eigenvectors().col(0);
  if (plane.normal.z() > 0.0) plane.normal = -plane.normal;
  plane.inliers = static_cast<int>(points.size());
  return plane;
}

// Robust sigma (1.4826 MAD) of the points' distances to the plane [m].
double ResidualSigma(const Plane& plane, const std::vector<Eigen::Vector3d>& points) {
  std::vector<double> residuals;
  for (const Eigen::Vector3d& p : points) residuals.push_back(plane.normal.dot(p - plane.point));
  const auto mid = residuals.begin() + static_cast<long>(residuals.size() / 2);
  std::nth_element(residuals.begin(), mid, residuals.end());
  const double median = *mid;
  for (double& r : residuals) r = std::abs(r - median);
  std::nth_element(residuals.begin(), mid, residuals.end());
  return 1.4826 * *mid;
}

// Ground plane around a rock: refit while dropping the points standing above it (the rock),
// with a threshold of 2.5 robust sigmas (MAD) of the kept points' residuals, at least 3 cm.
std::optional<Plane> FitBackgroundPlane(std::vector<Eigen::Vector3d> points) {
  constexpr int kMinPoints = 8;
  if (static_cast<int>(points.size()) < kMinPoints) return std::nullopt;
  Plane plane = FitPlane(points);
  for (int iteration = 0; iteration < 8; ++iteration) {
    std::vector<double> residuals;
    for (const Eigen::Vector3d& p : points) residuals.push_back(plane.normal.dot(p - plane.point));
    std::vector<double> sorted = residuals;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double median = sorted[sorted.size() / 2];
    for (double& r : sorted) r = std::abs(r - median);
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double threshold = std::max(0.03, 2.5 * 1.4826 * sorted[sorted.size() / 2]);
    std::vector<Eigen::Vector3d> kept;
    for (size_t i = 0; i < points.size(); ++i) {
      if (residuals[i] - median < threshold) kept.push_back(points[i]);
    }
    if (static_cast<int>(kept.size()) < kMinPoints) break;
    const bool unchanged = kept.size() == points.size();
    points = std::move(kept);
    plane = FitPlane(points);
    if (unchanged) break;
  }
  plane.residual_sigma = ResidualSigma(plane, points);
  return plane;
}

Rigid3d RockFromSite(const Eigen::Vector3d& foot, const Eigen::Vector3d& up) {
  Eigen::Vector3d x = Eigen::Vector3d::UnitX() - up.dot(Eigen::Vector3d::UnitX()) * up;
  if (x.norm() < 1e-6) x = Eigen::Vector3d::UnitY() - up.dot(Eigen::Vector3d::UnitY()) * up;
  x.normalize();
  Eigen::Matrix3d rotation;  // Rows: the rock axes in the site frame.
  rotation.row(0) = x;
  rotation.row(1) = up.cross(x);
  rotation.row(2) = up;
  return Rigid3d(rotation, -(rotation * foot));
}

class Extractor {
 public:
  // Only points that can matter are indexed: within the peak range of the camera plus the
  // widest neighbourhood (plane search), which also bounds the grid for clouds with far outliers.
  Extractor(const PointCloud& cloud, const RockExtractionOptions& options)
      : cloud_(cloud),
        options_(options),
        xy_(HorizontalPositions(cloud)),
        keep_(NearCamera(cloud, options.max_peak_range_m + 3.0)),
        grid_(xy_, options.peak_window_m / 5.0, &keep_) {}

  std::vector<int> FindPeakCandidates(RockExtractionSummary* summary) const {
    const int cells = grid_.nx() * grid_.ny();
    std::vector<int> top(cells, -1);
    std::vector<double> high(cells, -1e300), low(cells, 1e300);
    std::vector<int> count(cells, 0);
    tbb::parallel_for(0, cells, [&](int c) {
      for (const int* it = grid_.begin(c); it != grid_.end(c); ++it) {
        const double e = Elevation(*it);
        if (e > high[c] || (e == high[c] && *it < top[c])) {
          high[c] = e;
          top[c] = *it;
        }
        low[c] = std::min(low[c], e);
        ++count[c];
      }
    });
    std::vector<char> is_peak(cells, 0), in_range(cells, 1);
    tbb::parallel_for(0, grid_.ny(), [&](int cy) {
      for (int cx = 0; cx < grid_.nx(); ++cx) {
        const int c = grid_.Cell(cx, cy);
        if (top[c] < 0) continue;
        double window_low = 1e300;
        int points = 0;
        bool highest = true;
        for (int y = std::max(0, cy - 2); y <= std::min(grid_.ny() - 1, cy + 2) && highest; ++y) {
          for (int x = std::max(0, cx - 2); x <= std::min(grid_.nx() - 1, cx + 2); ++x) {
            const int o = grid_.Cell(x, y);
            if (top[o] < 0) continue;
            if (high[o] > high[c] || (high[o] == high[c] && top[o] < top[c])) {
              highest = false;
              break;
            }
            window_low = std::min(window_low, low[o]);
            points += count[o];
          }
        }
        if (!highest || points < options_.min_window_points ||
            high[c] - window_low <= options_.min_peak_relief_m) {
          continue;
        }
        is_peak[c] = 1;
        const Eigen::Vector3d d = cloud_.points[top[c]].position - cloud_.camera_center;
        in_range[c] = d.head<2>().norm() <= options_.max_peak_range_m;
      }
    });
    std::vector<int> peaks;
    for (int c = 0; c < cells; ++c) {
      if (!is_peak[c]) continue;
      ++summary->peak_candidates;
      if (!in_range[c]) {
        ++summary->beyond_range;
        continue;
      }
      peaks.push_back(top[c]);
    }
    return peaks;
  }

  // Steps 2-4 for one peak; nullopt when the rock is too low or its ground cannot be fitted.
  std::optional<ExtractedRock> Process(int peak_index) const {
    const Eigen::Vector3d peak = cloud_.points[peak_index].position;
    // Preliminary height from the window relief, to widen the ground search for big rocks.
    double window_low = 1e300;
    grid_.ForEachNear(peak.head<2>(), 0.5 * options_.peak_window_m,
                      [&](int j) { window_low = std::min(window_low, Elevation(j)); });
    const double relief = -peak.z() - window_low;
    // The ground must reach beyond the rock: when the fitted height says the rock is wider than
    // the neighbourhood (1.7 H + 0.3 m, the surface search's reach plus a margin), refit once
    // over the wider neighbourhood (at most 4 m: boulders bigger than that are not landmarks).
    // The rock's own points are left out of its ground (Mars rocks are about half as high as
    // they are wide, so the footprint reaches about H from the peak): with the range noise of a
    // far rock (eq. 4.3) the ground's robust threshold is several centimetres and would keep the
    // rock's lower flanks in the plane, lifting it and shrinking H.
    const auto fit = [&](double radius) {
      const double inner = std::min(0.5 * radius, options_.plane_exclusion_k * relief);
      std::vector<int> near;
      grid_.ForEachNear(peak.head<2>(), radius, [&](int j) {
        const double d = (cloud_.points[j].position - peak).head<2>().norm();
        if (d <= radius && d >= inner) near.push_back(j);
      });
      constexpr size_t kMaxPlanePoints = 800;
      const size_t stride = std::max<size_t>(1, near.size() / kMaxPlanePoints);
      std::vector<Eigen::Vector3d> sample;
      for (size_t k = 0; k < near.size(); k += stride)
        sample.push_back(cloud_.points[near[k]].position);
      return FitBackgroundPlane(std::move(sample));
    };
    constexpr double kMaxPlaneRadius = 4.0;
    const double radius = std::max(options_.plane_radius_m, 1.7 * relief + 0.3);
    std::optional<Plane> plane = fit(radius);
    if (plane) {
      const double wider =
          std::min(kMaxPlaneRadius, 1.7 * plane->normal.dot(peak - plane->point) + 0.3);
      if (wider > 1.25 * radius) {
        if (std::optional<Plane> refit = fit(wider)) plane = refit;
      }
    }
    if (!plane) return std::nullopt;
    ExtractedRock rock;
    rock.peak_index = peak_index;
    rock.peak = peak;
    rock.peak_covariance = cloud_.points[peak_index].covariance;
    rock.range_m = (peak - cloud_.camera_center).head<2>().norm();
    rock.plane_normal = plane->normal;
    rock.height_m = plane->normal.dot(peak - plane->point);
    rock.peak_foot = peak - rock.height_m * plane->normal;
    rock.background_points = plane->inliers;
    rock.ground_sigma_m = plane->residual_sigma;
    if (rock.height_m < options_.min_height_m) return std::nullopt;
    GrowSurface(*plane, &rock);
    rock.rock_from_site = RockFromSite(rock.peak_foot, plane->normal);
    return rock;
  }

  // Step 4 (after merging): the models, for rocks high enough.
  void FitModels(ExtractedRock* rock) const {
    if (!options_.fit_models || rock->height_m < options_.model_min_height_m) return;
    const std::vector<int>& surface = rock->surface_indices;
    const size_t stride = std::max<size_t>(1, (surface.size() + options_.max_model_points - 1) /
                                                  static_cast<size_t>(options_.max_model_points));
    std::vector<Eigen::Vector3d> points;
    for (size_t k = 0; k < surface.size(); k += stride) {
      points.push_back(rock->rock_from_site * cloud_.points[surface[k]].position);
    }
    RockModelParameters start;
    start.height = rock->height_m;
    // Keep one-sided views plausible: the surface points bound the rock's size and centre.
    const double reach = std::max({rock->surface_radius_m, 0.3 * rock->height_m, 0.03});
    RockModelFitOptions model = options_.model;
    model.max_height_m = std::min(model.max_height_m, 1.5 * rock->height_m + 0.05);
    model.max_radius_m = std::min(model.max_radius_m, 1.5 * reach + 0.05);
    model.max_center_offset_m = std::min(model.max_center_offset_m, reach);
    start.a = std::min(reach, 0.9 * model.max_radius_m);
    rock->models = FitAllRockModels(points, model, start);
  }

 private:
  static std::vector<Eigen::Vector2d> HorizontalPositions(const PointCloud& cloud) {
    std::vector<Eigen::Vector2d> xy;
    xy.reserve(cloud.points.size());
    for (const StereoPoint& p : cloud.points) xy.push_back(p.position.head<2>());
    return xy;
  }
  static std::vector<char> NearCamera(const PointCloud& cloud, double radius) {
    std::vector<char> keep(cloud.points.size());
    for (size_t i = 0; i < cloud.points.size(); ++i) {
      keep[i] = (cloud.points[i].position - cloud.camera_center).head<2>().norm() <= radius;
    }
    return keep;
  }
  double Elevation(int i) const { return -cloud_.points[i].position.z(); }

  // The ground's own scatter about its plane (noise and roughness, measured) is the yardstick:
  // the a-priori stereo sigma of a single point (eq. 4.3) grows as r^2 and, for dense stereo
  // whose neighbouring points share their correlation windows, overstates the relative height
  // error between neighbouring points several times, which would strip far rocks of their surface.
  bool AbovePlane(const Plane& plane, int j) const {
    const double h = plane.normal.dot(cloud_.points[j].position - plane.point);
    return h > std::max(options_.above_plane_m, options_.above_plane_sigmas * plane.residual_sigma);
  }

  // Ch. 2.2.2 steps 2-3: dynamic search range from 0.3 H to 1.7 H by MaxD_Neighbor steps.
  void GrowSurface(const Plane& plane, ExtractedRock* rock) const {
    const double h = rock->height_m;
    const double start_radius = options_.surface_k_min * h;
    const double max_radius = options_.surface_k_max * h;
    const double cap = grid_.cell();  // Nearest-neighbour distances are searched up to one cell.
    const Eigen::Vector2d peak_xy = rock->peak.head<2>();
    // The points above the plane that a surface point or its nearest neighbour can be (within
    // max_radius + cap horizontally; 2 cap keeps a margin for rounding), in voxels of an eighth of
    // the largest query radius (steps and neighbour distances are <= cap) laid from the peak.
    std::vector<int> above;
    grid_.ForEachNear(peak_xy, max_radius + 2.0 * cap, [&](int j) {
      if ((cloud_.points[j].position.head<2>() - peak_xy).norm() <= max_radius + 2.0 * cap &&
          AbovePlane(plane, j)) {
        above.push_back(j);
      }
    });
    const VoxelIndex voxels(cloud_.points, above, rock->peak, cap / 8.0);
    std::unordered_set<int> found;
    std::vector<int> frontier;
    double max_neighbour = 0.0;
    const auto add = [&](int j) {
      if (!found.insert(j).second) return;
      frontier.push_back(j);
      max_neighbour =
          std::max(max_neighbour, voxels.NearestDistance(cloud_.points[j].position, j, cap));
    };
    add(rock->peak_index);
    for (int j : above) {
      if ((cloud_.points[j].position.head<2>() - peak_xy).norm() <= start_radius) add(j);
    }
    while (!frontier.empty()) {
      const std::vector<int> last = std::move(frontier);
      frontier.clear();
      const double step = std::max(max_neighbour, 1e-3);
      for (int f : last) {
        voxels.ForEachWithin(cloud_.points[f].position, step, [&](int j) {
          if ((cloud_.points[j].position.head<2>() - peak_xy).norm() <= max_radius) add(j);
        });
      }
    }
    rock->surface_indices.assign(found.begin(), found.end());
    std::sort(rock->surface_indices.begin(), rock->surface_indices.end());
    for (int j : rock->surface_indices) {
      rock->surface_radius_m =
          std::max(rock->surface_radius_m, (cloud_.points[j].position.head<2>() - peak_xy).norm());
    }
  }

  const PointCloud& cloud_;
  const RockExtractionOptions& options_;
  std::vector<Eigen::Vector2d> xy_;
  std::vector<char> keep_;
  PointGrid grid_;
};

// The rock grown from each peak (in parallel); none where the peak gives none.
std::vector<std::optional<ExtractedRock>> ProcessPeaks(const Extractor& extractor,
                                                       const std::vector<int>& peaks) {
  std::vector<std::optional<ExtractedRock>> processed(peaks.size());
  tbb::parallel_for(size_t{0}, peaks.size(),
                    [&](size_t k) { processed[k] = extractor.Process(peaks[k]); });
  return processed;
}

// The rocks, highest first (ties: the lower peak index); counts the peaks that gave none as too
// low.
std::vector<ExtractedRock> RocksByHeight(std::vector<std::optional<ExtractedRock>> processed,
                                         RockExtractionSummary* s) {
  std::vector<ExtractedRock> candidates;
  for (auto& rock : processed) {
    if (rock) {
      candidates.push_back(std::move(*rock));
    } else {
      ++s->too_low;
    }
  }
  std::sort(
      candidates.begin(), candidates.end(), [](const ExtractedRock& a, const ExtractedRock& b) {
        return a.height_m != b.height_m ? a.height_m > b.height_m : a.peak_index < b.peak_index;
      });
  return candidates;
}

// The rocks kept so far, highest first, their peaks in a 1 m hash grid.
class KeptRocks {
 public:
  // A peak on a higher rock's surface is part of that rock; so is a lower peak closer to a higher
  // one than the higher rock's reach plus twice their separation's sigma (range noise smears a
  // far rock's points along the line of sight).
  bool Swallow(const ExtractedRock& rock) const {
    const long cx = std::lround(std::floor(rock.peak.x() / kCell));
    const long cy = std::lround(std::floor(rock.peak.y() / kCell));
    for (long dy = -3; dy <= 3; ++dy) {
      for (long dx = -3; dx <= 3; ++dx) {
        const auto it = cells_.find(Key(cx + dx, cy + dy));
        if (it == cells_.end()) continue;
        for (int k : it->second) {
          const ExtractedRock& high = rocks_[k];
          const Eigen::Vector2d d = (rock.peak - high.peak).head<2>();
          const double distance = d.norm();
          if (distance < 1e-9) return true;
          const Eigen::Vector2d u = d / distance;
          const double sigma = std::sqrt(
              u.dot((rock.peak_covariance + high.peak_covariance).topLeftCorner<2, 2>() * u));
          const double reach = std::max(high.surface_radius_m, 0.5 * high.height_m);
          if (distance <= std::min(reach + 2.0 * sigma, 3.0 * kCell)) return true;
        }
      }
    }
    return false;
  }

  // Keeps `rock` with the next id.
  void Add(ExtractedRock rock) {
    rock.id = static_cast<int>(rocks_.size()) + 1;
    cells_[Key(std::lround(std::floor(rock.peak.x() / kCell)),
               std::lround(std::floor(rock.peak.y() / kCell)))]
        .push_back(static_cast<int>(rocks_.size()));
    rocks_.push_back(std::move(rock));
  }

  std::vector<ExtractedRock> Release() { return std::move(rocks_); }

 private:
  static constexpr double kCell = 1.0;
  static long long Key(long cx, long cy) {
    return (static_cast<long long>(cx) << 32) ^ (cy & 0xffffffffLL);
  }
  std::vector<ExtractedRock> rocks_;
  std::unordered_map<long long, std::vector<int>> cells_;
};

// Keeps each rock, highest first, unless a kept rock owns its peak point or swallows it; a kept
// rock owns its surface points.
std::vector<ExtractedRock> MergeRocks(std::vector<ExtractedRock> candidates, size_t point_count,
                                      RockExtractionSummary* s) {
  std::vector<char> owned(point_count, 0);
  KeptRocks kept;
  for (ExtractedRock& rock : candidates) {
    if (owned[rock.peak_index] || kept.Swallow(rock)) {
      ++s->merged;
      continue;
    }
    for (int j : rock.surface_indices) owned[j] = 1;
    kept.Add(std::move(rock));
  }
  return kept.Release();
}

}  // namespace

void RockExtractionOptions::Check() const {
  RequireOption(peak_window_m > 0.05 && peak_window_m < 10.0, "RockExtractionOptions.peak_window_m",
                "between 0.05 and 10 m");
  RequireOption(min_peak_relief_m > 0.0, "RockExtractionOptions.min_peak_relief_m", "> 0 m");
  RequireOption(min_window_points >= 1, "RockExtractionOptions.min_window_points", ">= 1");
  RequireOption(max_peak_range_m > 0.0, "RockExtractionOptions.max_peak_range_m", "> 0 m");
  RequireOption(plane_radius_m > 0.0, "RockExtractionOptions.plane_radius_m", "> 0 m");
  RequireOption(plane_exclusion_k >= 0.0, "RockExtractionOptions.plane_exclusion_k", ">= 0");
  RequireOption(min_height_m >= 0.0, "RockExtractionOptions.min_height_m", ">= 0 m");
  RequireOption(surface_k_min > 0.0 && surface_k_max > surface_k_min,
                "RockExtractionOptions.surface_k_max", "0 < surface_k_min < surface_k_max");
  RequireOption(above_plane_m >= 0.0 && above_plane_sigmas >= 0.0,
                "RockExtractionOptions.above_plane_m", "thresholds >= 0");
  RequireOption(max_model_points >= 5, "RockExtractionOptions.max_model_points", ">= 5");
  RequireOption(model_min_height_m >= 0.0, "RockExtractionOptions.model_min_height_m", ">= 0 m");
  model.Check();
}

std::vector<ExtractedRock> ExtractRocks(const PointCloud& cloud,
                                        const RockExtractionOptions& options,
                                        RockExtractionSummary* summary,
                                        const ProgressCallback& progress) {
  options.Check();
  CheckPointCloud(cloud, cloud.frame, /*allow_empty=*/true);
  RockExtractionSummary local;
  RockExtractionSummary& s = summary ? *summary : local;
  s = RockExtractionSummary{};
  s.points = static_cast<int>(cloud.points.size());
  if (cloud.points.empty()) return {};
  const auto report = [&](double fraction, std::string_view stage) {
    if (progress && !progress(fraction, stage)) throw Error("cancelled during rock extraction");
  };
  report(0.0, "peaks");
  const Extractor extractor(cloud, options);
  const std::vector<int> peaks = extractor.FindPeakCandidates(&s);
  report(0.3, "rocks");
  std::vector<std::optional<ExtractedRock>> processed = ProcessPeaks(extractor, peaks);
  report(0.9, "merge");
  std::vector<ExtractedRock> rocks =
      MergeRocks(RocksByHeight(std::move(processed), &s), cloud.points.size(), &s);
  report(0.95, "models");
  tbb::parallel_for(size_t{0}, rocks.size(), [&](size_t k) { extractor.FitModels(&rocks[k]); });
  for (const ExtractedRock& rock : rocks) s.modeled += rock.modeled() ? 1 : 0;
  s.rocks = static_cast<int>(rocks.size());
  report(1.0, "done");
  return rocks;
}

}  // namespace areomap
