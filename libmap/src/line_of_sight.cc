#include "areomap/map/line_of_sight.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <vector>

#include <tbb/parallel_for.h>

#include "areomap/map/error.h"
#include "areomap/map/geodesy.h"

namespace areomap {
namespace {

enum Verdict : uint8_t { kKept = 0, kBuried = 1, kFloating = 2 };

struct SectorPoint {
  size_t index = 0;        // into the cloud
  double rho = 0.0;        // horizontal distance from the camera [m]
  double elevation = 0.0;  // sight-line angle above the horizontal [rad]
  double behind_of = 0.0;  // this point lies surely behind every point with rho below this [m]
};

// Counts, as a sweep inserts points, how many of them have an elevation rank below a given one
// (a Fenwick tree over ranks).
class RankCounter {
 public:
  explicit RankCounter(size_t n) : tree_(n + 1, 0) {}
  void Insert(size_t rank) {
    for (size_t i = rank + 1; i < tree_.size(); i += i & (~i + 1)) ++tree_[i];
    ++inserted_;
  }
  size_t Inserted() const { return inserted_; }
  // Inserted points with rank < `rank`.
  size_t Below(size_t rank) const {
    size_t sum = 0;
    for (size_t i = rank; i > 0; i -= i & (~i + 1)) sum += tree_[i];
    return sum;
  }

 private:
  std::vector<size_t> tree_;
  size_t inserted_ = 0;
};

bool Condemns(size_t against, size_t compared, const LineOfSightOptions& o) {
  return against >= static_cast<size_t>(o.min_count) &&
         static_cast<double>(against) >= o.max_fraction * static_cast<double>(compared);
}

// Judges the points of one azimuth sector.
void JudgeSector(std::vector<SectorPoint>& sector, const LineOfSightOptions& o,
                 std::vector<uint8_t>* verdicts) {
  const size_t n = sector.size();
  if (n <= static_cast<size_t>(o.min_count)) return;
  std::sort(sector.begin(), sector.end(),
            [](const SectorPoint& a, const SectorPoint& b) { return a.rho < b.rho; });
  std::vector<double> elevations(n);
  for (size_t i = 0; i < n; ++i) elevations[i] = sector[i].elevation;
  std::sort(elevations.begin(), elevations.end());
  const auto rank_of = [&](double e) {  // points with elevation below e
    return static_cast<size_t>(std::lower_bound(elevations.begin(), elevations.end(), e) -
                               elevations.begin());
  };
  const double tolerance = RadFromDeg(o.elevation_tolerance_deg);
  std::vector<size_t> by_behind_of(n);
  std::iota(by_behind_of.begin(), by_behind_of.end(), size_t{0});
  std::sort(by_behind_of.begin(), by_behind_of.end(),
            [&](size_t a, size_t b) { return sector[a].behind_of < sector[b].behind_of; });

  // Buried: for each P in increasing behind_of, the points in front of it (rho < behind_of_P)
  // are inserted in increasing rho; count those seen higher than P.
  RankCounter in_front(n);
  for (const size_t q : by_behind_of) {
    const SectorPoint& p = sector[q];
    while (in_front.Inserted() < n && sector[in_front.Inserted()].rho < p.behind_of) {
      in_front.Insert(rank_of(sector[in_front.Inserted()].elevation));
    }
    const size_t higher = in_front.Inserted() - in_front.Below(rank_of(p.elevation + tolerance));
    if (Condemns(higher, in_front.Inserted(), o)) (*verdicts)[p.index] = kBuried;
  }

  // Floating: for each P in decreasing rho, the points surely behind it (behind_of > rho_P) are
  // inserted in decreasing behind_of; count those seen lower than P. Buried points are no
  // witnesses: the rover deck's mismatches, far and steep, would condemn the good ground in
  // front of them where nothing else lies behind it (at the image's edges).
  RankCounter behind(n);
  for (size_t i = n, next = n; i-- > 0;) {
    const SectorPoint& p = sector[i];
    for (; next > 0 && sector[by_behind_of[next - 1]].behind_of > p.rho; --next) {
      const SectorPoint& q = sector[by_behind_of[next - 1]];
      if ((*verdicts)[q.index] != kBuried) behind.Insert(rank_of(q.elevation));
    }
    const size_t lower = behind.Below(rank_of(p.elevation - tolerance));
    if (Condemns(lower, behind.Inserted(), o) && (*verdicts)[p.index] == kKept) {
      (*verdicts)[p.index] = kFloating;
    }
  }
}

}  // namespace

void LineOfSightOptions::Check() const {
  RequireOption(sector_deg > 0.0 && sector_deg <= 10.0, "LineOfSightOptions.sector_deg",
                "an azimuth sector of (0, 10] degrees");
  RequireOption(elevation_tolerance_deg >= 0.0 && elevation_tolerance_deg < 90.0,
                "LineOfSightOptions.elevation_tolerance_deg", "[0, 90) degrees");
  RequireOption(range_sigmas >= 0.0 && std::isfinite(range_sigmas),
                "LineOfSightOptions.range_sigmas", ">= 0");
  RequireOption(min_gap_m >= 0.0 && std::isfinite(min_gap_m), "LineOfSightOptions.min_gap_m",
                ">= 0 m");
  RequireOption(max_fraction > 0.0 && max_fraction <= 1.0, "LineOfSightOptions.max_fraction",
                "(0, 1]");
  RequireOption(min_count >= 1, "LineOfSightOptions.min_count", ">= 1");
}

LineOfSightDrops DropLineOfSightConflicts(PointCloud* cloud, const LineOfSightOptions& options,
                                          const std::vector<StereoPoint>& witnesses) {
  options.Check();
  const Eigen::Vector3d& c = cloud->camera_center;
  const int sectors = static_cast<int>(std::ceil(360.0 / options.sector_deg));
  std::vector<std::vector<SectorPoint>> by_sector(static_cast<size_t>(sectors));
  const size_t n = cloud->points.size();
  for (size_t i = 0; i < n + witnesses.size(); ++i) {  // witnesses: index >= n
    const StereoPoint& p = i < n ? cloud->points[i] : witnesses[i - n];
    const Eigen::Vector3d d = p.position - c;
    const double rho = std::hypot(d.x(), d.y());
    if (rho < 0.01) continue;
    const Eigen::Vector3d horizontal(d.x() / rho, d.y() / rho, 0.0);
    const double rho_sigma = std::sqrt(std::max(0.0, horizontal.dot(p.covariance * horizontal)));
    double azimuth = DegFromRad(std::atan2(d.y(), d.x()));
    if (azimuth < 0.0) azimuth += 360.0;
    const int s = std::min(sectors - 1, static_cast<int>(azimuth / options.sector_deg));
    by_sector[static_cast<size_t>(s)].push_back(
        {i, rho, std::atan2(-d.z(), rho),
         rho - options.range_sigmas * rho_sigma - options.min_gap_m});
  }
  std::vector<uint8_t> verdicts(n + witnesses.size(), kKept);
  tbb::parallel_for(size_t{0}, by_sector.size(),
                    [&](size_t s) { JudgeSector(by_sector[s], options, &verdicts); });
  LineOfSightDrops drops;
  size_t kept = 0;
  for (size_t i = 0; i < n; ++i) {
    drops.buried += verdicts[i] == kBuried;
    drops.floating += verdicts[i] == kFloating;
    if (verdicts[i] == kKept) cloud->points[kept++] = cloud->points[i];
  }
  cloud->points.resize(kept);
  return drops;
}

}  // namespace areomap
