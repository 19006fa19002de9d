#include "areomap/samples/scene.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <sstream>

#include "areomap/map/error.h"
#include "noise.h"

namespace areomap {
namespace {

// Crater profile as a function of the normalised elliptical radius rho (1 at the rim crest),
// relative to the surroundings [m].
double CraterProfile(const Crater& c, double rho) {
  const double floor_depth = c.depth - c.rim_height;  // Floor below the surroundings.
  if (rho <= 1.0) {
    const double f = c.flat_floor ? c.floor_fraction : 0.0;
    if (rho <= f) return -floor_depth;
    const double s = (rho - f) / (1.0 - f);
    // Bowl: parabolic; flat floor: a wall of nearly constant slope.
    return -floor_depth + c.depth * (c.flat_floor ? std::pow(s, 1.3) : s * s);
  }
  // Ejecta thickness falls off as rho^-3 (McGetchin et al. 1973), cut at 3 rim radii.
  if (rho >= 3.0) return 0.0;
  const double cut = 1.0 / 27.0;
  return c.rim_height * (1.0 / (rho * rho * rho) - cut) / (1.0 - cut);
}

double DistanceToPolyline(const Eigen::Vector2d& p, const std::vector<Eigen::Vector2d>& line) {
  if (line.size() == 1) return (p - line.front()).norm();
  double best = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i + 1 < line.size(); ++i) {
    const Eigen::Vector2d d = line[i + 1] - line[i];
    const double t = std::clamp((p - line[i]).dot(d) / std::max(d.squaredNorm(), 1e-12), 0.0, 1.0);
    best = std::min(best, (p - (line[i] + t * d)).norm());
  }
  return best;
}

// Height of a rock's shape in its own upright frame at (x, y) [m].
double ShapeHeight(const Rock& r, double x, double y) {
  switch (r.shape) {
    case RockShape::kHemispheroid: {
      const double q = (x * x + y * y) / (r.a * r.a);
      return q < 1.0 ? r.height * std::sqrt(1.0 - q) : 0.0;
    }
    case RockShape::kSemiEllipsoid: {
      const double q = x * x / (r.a * r.a) + y * y / (r.b * r.b);
      return q < 1.0 ? r.height * std::sqrt(1.0 - q) : 0.0;
    }
    case RockShape::kCone: {
      const double q = std::hypot(x, y) / r.a;
      return q < 1.0 ? r.height * (1.0 - q) : 0.0;
    }
    case RockShape::kTetrahedron: {
      // Base triangle inscribed in the circle of radius a, first vertex on +x; apex above the
      // centroid. Height is proportional to the distance to the nearest base edge.
      const double inradius = 0.5 * r.a;
      double nearest = inradius;
      for (int i = 0; i < 3; ++i) {
        const double normal = std::numbers::pi / 3.0 + 2.0 * std::numbers::pi / 3.0 * i;
        nearest = std::min(nearest, inradius - (x * std::cos(normal) + y * std::sin(normal)));
      }
      return nearest > 0.0 ? r.height * nearest / inradius : 0.0;
    }
  }
  return 0.0;
}

// Rotation taking the rock's frame to the local level frame: azimuth about z after the tilts
// alpha (about x) and beta (about y) of eq. 2.10.
Eigen::Matrix3d RockRotation(const Rock& r) {
  const Eigen::Matrix3d rz = Eigen::AngleAxisd(r.azimuth, Eigen::Vector3d::UnitZ()).matrix();
  const Eigen::Matrix3d rx = Eigen::AngleAxisd(r.tilt_x, Eigen::Vector3d::UnitX()).matrix();
  const Eigen::Matrix3d ry = Eigen::AngleAxisd(r.tilt_y, Eigen::Vector3d::UnitY()).matrix();
  return rz * ry * rx;
}

// An older crater: shallower, its rim lower still, its floor partly filled (SceneOptions::
// crater_max_degradation). Keeps depth > rim_height.
void Degrade(double g, Crater* c) {
  c->depth *= 1.0 - g;
  c->rim_height *= (1.0 - g) * (1.0 - g);
  if (g > 0.3) {
    c->flat_floor = true;
    c->floor_fraction = std::max(c->floor_fraction, g);
  }
}

// Explicit craters, then random craters (fresh, d/D ~ 0.2, unless degraded) spaced as the options
// say, off the rock path, numbered from 1.
std::vector<Crater> PlaceCraters(const SceneOptions& options, std::mt19937& rng,
                                 std::uniform_real_distribution<double>& unit) {
  std::vector<Crater> craters = options.explicit_craters;
  const double half = options.half_extent_m;
  const double log_min = std::log(options.crater_min_diameter_m);
  const double log_max = std::log(options.crater_max_diameter_m);
  for (int attempt = 0;
       static_cast<int>(craters.size()) <
           options.crater_count + static_cast<int>(options.explicit_craters.size()) &&
       attempt < 100 * (options.crater_count + 1);
       ++attempt) {
    Crater c;
    const double diameter = std::exp(log_min + (log_max - log_min) * unit(rng));
    c.semi_major = diameter / 2.0;
    c.semi_minor = c.semi_major * (0.85 + 0.15 * unit(rng));
    c.angle = std::numbers::pi * unit(rng);
    c.center = {(2.0 * unit(rng) - 1.0) * (half - c.semi_major),
                (2.0 * unit(rng) - 1.0) * (half - c.semi_major)};
    c.depth = diameter * (0.15 + 0.07 * unit(rng));
    c.rim_height = diameter * (0.03 + 0.02 * unit(rng));
    c.flat_floor = unit(rng) < 0.3;
    c.floor_fraction = c.flat_floor ? 0.3 + 0.2 * unit(rng) : 0.0;
    if (options.crater_max_degradation > 0.0)
      Degrade(options.crater_max_degradation * unit(rng), &c);
    const bool overlaps = std::any_of(craters.begin(), craters.end(), [&](const Crater& o) {
      return (o.center - c.center).norm() <
             options.crater_min_spacing * (o.semi_major + c.semi_major);
    });
    const bool on_path = !options.rock_path.empty() &&
                         DistanceToPolyline(c.center, options.rock_path) < c.semi_major * 1.5;
    if (!overlaps && !on_path) craters.push_back(c);
  }
  for (size_t i = 0; i < craters.size(); ++i) craters[i].id = static_cast<int>(i) + 1;
  return craters;
}

// Rock diameters for inverse-CDF sampling: the cumulative number density over kBins bins.
struct RockSizeTable {
  static constexpr int kBins = 2000;
  std::vector<double> cdf;  // kBins + 1 values [rocks / m^2].
  double d_min = 0.0;       // [m]
  double step = 0.0;        // Bin width [m].
  double rocks_per_m2 = 0.0;
};

RockSizeTable TabulateRockSizes(const SceneOptions& options) {
  const double k = options.rock_abundance_k;
  const double q = 1.79 + 0.152 / k;
  // Number density n(D) = -dF/dD / (pi D^2 / 4), tabulated for inverse-CDF sampling.
  constexpr int kBins = RockSizeTable::kBins;
  RockSizeTable sizes;
  std::vector<double>& cdf = sizes.cdf;
  cdf.assign(kBins + 1, 0.0);
  const double d_min = options.rock_min_diameter_m, d_max = options.rock_max_diameter_m;
  const double step = (d_max - d_min) / kBins;
  for (int i = 0; i < kBins; ++i) {
    const double d = d_min + (i + 0.5) * step;
    cdf[i + 1] = cdf[i] + k * q * std::exp(-q * d) / (std::numbers::pi * d * d / 4.0) * step;
  }
  sizes.d_min = d_min;
  sizes.step = step;
  sizes.rocks_per_m2 = cdf.back();
  return sizes;
}

// The box rock candidates are drawn in: the rock path's bounding box grown by the corridor,
// within the scene.
struct RockBox {
  Eigen::Vector2d lo, hi;
  double Area() const { return (hi - lo).prod(); }
};

RockBox RockSamplingBox(const SceneOptions& options) {
  const double half = options.half_extent_m;
  Eigen::Vector2d lo = options.rock_path.front(), hi = lo;
  for (const auto& p : options.rock_path) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  lo.array() -= options.rock_corridor_m;
  hi.array() += options.rock_corridor_m;
  lo = lo.cwiseMax(Eigen::Vector2d::Constant(-half));
  hi = hi.cwiseMin(Eigen::Vector2d::Constant(half));
  return {lo, hi};
}

// One rock candidate anywhere in the box (every draw is made, whether or not it is kept).
Rock DrawRockCandidate(const SceneOptions& options, const RockSizeTable& sizes, const RockBox& box,
                       std::mt19937& rng, std::uniform_real_distribution<double>& unit) {
  constexpr int kBins = RockSizeTable::kBins;
  const std::vector<double>& cdf = sizes.cdf;
  const Eigen::Vector2d& lo = box.lo;
  const Eigen::Vector2d& hi = box.hi;
  const double tilt_max = options.rock_max_tilt_deg * std::numbers::pi / 180.0;
  const Eigen::Vector2d p(lo.x() + (hi.x() - lo.x()) * unit(rng),
                          lo.y() + (hi.y() - lo.y()) * unit(rng));
  const double u = unit(rng) * cdf.back();
  const int bin = static_cast<int>(std::upper_bound(cdf.begin(), cdf.end(), u) - cdf.begin()) - 1;
  Rock r;
  const double diameter = sizes.d_min + (std::clamp(bin, 0, kBins - 1) + unit(rng)) * sizes.step;
  r.shape = static_cast<RockShape>(static_cast<int>(unit(rng) * 4.0) % 4);
  r.center = p;
  r.a = diameter / 2.0;
  r.b = r.shape == RockShape::kSemiEllipsoid ? r.a * (0.6 + 0.4 * unit(rng)) : r.a;
  r.height = std::clamp(diameter * (0.3 + 0.3 * unit(rng)), 0.05, 0.6);
  r.azimuth = 2.0 * std::numbers::pi * unit(rng);
  const bool tilted = unit(rng) < 0.3;
  r.tilt_x = tilted ? tilt_max * (2.0 * unit(rng) - 1.0) : 0.0;
  r.tilt_y = tilted ? tilt_max * (2.0 * unit(rng) - 1.0) : 0.0;
  return r;
}

// Stopping at max_rocks would thin the rocks below the requested k everywhere: refuse instead.
[[noreturn]] void ThrowTooManyRocks(const SceneOptions& options, long draws, long candidates) {
  throw Error(
      "SceneOptions.max_rocks: " + std::to_string(options.max_rocks) + " rocks reached after " +
      std::to_string(draws) + " of " + std::to_string(candidates) + " draws at rock_abundance_k " +
      std::to_string(options.rock_abundance_k) + "; raise max_rocks or lower the abundance");
}

// A uniform grid of n x n cells over the scene, each listing the rocks whose footprint may
// reach into it.
std::vector<std::vector<int>> GridRocks(const std::vector<Rock>& rocks, double half, double cell_m,
                                        int n) {
  std::vector<std::vector<int>> grid(static_cast<size_t>(n) * n);
  for (size_t i = 0; i < rocks.size(); ++i) {
    const Rock& r = rocks[i];
    const double reach = r.FootprintRadius();
    const int c0 = std::max(0, static_cast<int>((r.center.x() - reach + half) / cell_m));
    const int c1 = std::min(n - 1, static_cast<int>((r.center.x() + reach + half) / cell_m));
    const int r0 = std::max(0, static_cast<int>((r.center.y() - reach + half) / cell_m));
    const int r1 = std::min(n - 1, static_cast<int>((r.center.y() + reach + half) / cell_m));
    for (int row = r0; row <= r1; ++row) {
      for (int col = c0; col <= c1; ++col) {
        grid[static_cast<size_t>(row) * n + col].push_back(static_cast<int>(i));
      }
    }
  }
  return grid;
}

}  // namespace

std::string ToString(RockShape shape) {
  switch (shape) {
    case RockShape::kHemispheroid:
      return "hemispheroid";
    case RockShape::kSemiEllipsoid:
      return "semi-ellipsoid";
    case RockShape::kCone:
      return "cone";
    case RockShape::kTetrahedron:
      return "tetrahedron";
  }
  return "unknown";
}

RockShape RockShapeFromString(std::string_view text) {
  for (RockShape s : {RockShape::kHemispheroid, RockShape::kSemiEllipsoid, RockShape::kCone,
                      RockShape::kTetrahedron}) {
    if (ToString(s) == text) return s;
  }
  throw Error("unknown rock shape '" + std::string(text) +
              "': expected hemispheroid, semi-ellipsoid, cone or tetrahedron");
}

double Rock::FootprintRadius() const {
  const double r = std::max(a, b);
  return r + height * std::sin(std::max(std::abs(tilt_x), std::abs(tilt_y)));
}

double Rock::HeightAbove(const Eigen::Vector2d& p) const {
  const Eigen::Vector2d d = p - center;
  if (d.squaredNorm() > FootprintRadius() * FootprintRadius()) return 0.0;
  if (tilt_x == 0.0 && tilt_y == 0.0) {
    const double c = std::cos(azimuth), s = std::sin(azimuth);
    return ShapeHeight(*this, c * d.x() + s * d.y(), -s * d.x() + c * d.y());
  }
  // Tilted: find z with R^T (dx, dy, z) on the upright surface (fixed-point iteration).
  const Eigen::Matrix3d rock_from_level = RockRotation(*this).transpose();
  double z = 0.0;
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d q = rock_from_level * Eigen::Vector3d(d.x(), d.y(), z);
    const double surface = ShapeHeight(*this, q.x(), q.y());
    if (surface <= 0.0 && i > 0) return 0.0;
    z += (surface - q.z()) / rock_from_level(2, 2);
  }
  return std::max(z, 0.0);
}

void SceneOptions::Check() const {
  RequireOption(half_extent_m > 0.0 && half_extent_m <= 20000.0, "SceneOptions.half_extent_m",
                "0 < m <= 20000");
  RequireOption(roughness_m >= 0.0, "SceneOptions.roughness_m", ">= 0");
  RequireOption(roughness_wavelength_m > 0.0, "SceneOptions.roughness_wavelength_m", "> 0");
  RequireOption(crater_count >= 0, "SceneOptions.crater_count", ">= 0");
  RequireOption(crater_max_degradation >= 0.0 && crater_max_degradation <= 0.9,
                "SceneOptions.crater_max_degradation", "0..0.9");
  RequireOption(crater_min_spacing >= 0.5 && crater_min_spacing <= 3.0,
                "SceneOptions.crater_min_spacing", "0.5..3");
  RequireOption(crater_min_diameter_m > 0.0 && crater_max_diameter_m >= crater_min_diameter_m,
                "SceneOptions.crater_min_diameter_m", "0 < min <= crater_max_diameter_m");
  RequireOption(rock_abundance_k > 0.0 && rock_abundance_k < 1.0, "SceneOptions.rock_abundance_k",
                "0 < k < 1");
  RequireOption(rock_min_diameter_m > 0.0 && rock_max_diameter_m > rock_min_diameter_m,
                "SceneOptions.rock_min_diameter_m", "0 < min < rock_max_diameter_m");
  RequireOption(rock_max_tilt_deg >= 0.0 && rock_max_tilt_deg <= 45.0,
                "SceneOptions.rock_max_tilt_deg", "0..45 degrees");
  RequireOption(rock_corridor_m >= 0.0, "SceneOptions.rock_corridor_m", ">= 0");
  RequireOption(max_rocks >= 0, "SceneOptions.max_rocks", ">= 0");
  for (const Crater& c : explicit_craters) {
    RequireOption(c.semi_major >= c.semi_minor && c.semi_minor > 0.0 && c.depth > c.rim_height &&
                      c.rim_height >= 0.0,
                  "SceneOptions.explicit_craters",
                  "semi_major >= semi_minor > 0 and depth > rim_height >= 0");
  }
}

Scene::Scene(const SceneOptions& options) : options_(options) {
  options_.Check();
  std::mt19937 rng(options_.seed);
  noise_seed_ = static_cast<uint32_t>(rng());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  craters_ = PlaceCraters(options_, rng, unit);

  // Rocks along the path, diameters from the Golombek-Rapp size-frequency distribution.
  if (options_.rock_path.empty() || options_.max_rocks == 0) return;
  const RockSizeTable sizes = TabulateRockSizes(options_);
  const RockBox box = RockSamplingBox(options_);
  const auto candidates = static_cast<long>(std::llround(sizes.rocks_per_m2 * box.Area()));
  for (long i = 0; i < candidates; ++i) {
    if (static_cast<int>(rocks_.size()) == options_.max_rocks) {
      ThrowTooManyRocks(options_, i, candidates);
    }
    Rock r = DrawRockCandidate(options_, sizes, box, rng, unit);
    if (DistanceToPolyline(r.center, options_.rock_path) > options_.rock_corridor_m) continue;
    // Rocks sit on the plains, not on crater walls or floors.
    if (CraterRelief(r.center.x(), r.center.y()) < -0.05) continue;
    r.ground_z = GroundHeightAt(r.center.x(), r.center.y());
    r.id = static_cast<int>(rocks_.size()) + 1;
    rocks_.push_back(r);
  }
  rock_grid_n_ = static_cast<int>(std::ceil(2.0 * options_.half_extent_m / rock_cell_m_));
  rock_grid_ = GridRocks(rocks_, options_.half_extent_m, rock_cell_m_, rock_grid_n_);
}

double Scene::Background(double x, double y) const {
  return options_.base_elevation_m +
         options_.roughness_m * 1.8 *
             internal::FractalNoise(x, y, options_.roughness_wavelength_m, 7, 0.5, noise_seed_);
}

double Scene::CraterRelief(double x, double y) const {
  double relief = 0.0;
  for (const Crater& c : craters_) {
    const Eigen::Vector2d d = Eigen::Vector2d(x, y) - c.center;
    if (d.squaredNorm() > 9.0 * c.semi_major * c.semi_major) continue;
    const double cs = std::cos(c.angle), sn = std::sin(c.angle);
    const double u = (cs * d.x() + sn * d.y()) / c.semi_major;
    const double v = (-sn * d.x() + cs * d.y()) / c.semi_minor;
    relief += CraterProfile(c, std::hypot(u, v));
  }
  return relief;
}

double Scene::RockRelief(double x, double y) const {
  if (rock_grid_n_ == 0) return -std::numeric_limits<double>::infinity();
  const double half = options_.half_extent_m;
  const int col = static_cast<int>((x + half) / rock_cell_m_);
  const int row = static_cast<int>((y + half) / rock_cell_m_);
  if (col < 0 || row < 0 || col >= rock_grid_n_ || row >= rock_grid_n_) {
    return -std::numeric_limits<double>::infinity();
  }
  double top = -std::numeric_limits<double>::infinity();
  for (int index : rock_grid_[static_cast<size_t>(row) * rock_grid_n_ + col]) {
    const Rock& r = rocks_[static_cast<size_t>(index)];
    const double above = r.HeightAbove({x, y});
    if (above > 0.0) top = std::max(top, r.ground_z + above);
  }
  return top;
}

double Scene::GroundHeightAt(double x, double y) const {
  return Background(x, y) + CraterRelief(x, y);
}

double Scene::HeightAt(double x, double y) const {
  return std::max(GroundHeightAt(x, y), RockRelief(x, y));
}

double Scene::AlbedoAt(double x, double y) const {
  if (RockRelief(x, y) > GroundHeightAt(x, y)) {
    return 0.14 + 0.04 * internal::FractalNoise(x, y, 0.3, 4, 0.6, noise_seed_ + 17u);
  }
  const double regional = internal::FractalNoise(x, y, 80.0, 4, 0.5, noise_seed_ + 31u);
  const double fine = internal::FractalNoise(x, y, 0.5, 5, 0.85, noise_seed_ + 53u);
  // Fine texture (50 cm down to 3 cm) gives stereo matching something to hold on to.
  return std::clamp(0.24 + 0.06 * regional + 0.12 * fine, 0.05, 0.6);
}

Eigen::Vector3d Scene::NormalAt(double x, double y, double step) const {
  const double dzdx = (HeightAt(x + step, y) - HeightAt(x - step, y)) / (2.0 * step);
  const double dzdy = (HeightAt(x, y + step) - HeightAt(x, y - step)) / (2.0 * step);
  return Eigen::Vector3d(-dzdx, -dzdy, 1.0).normalized();
}

int Scene::RockNear(const Eigen::Vector2d& enu, double min_height_m, double max_gap_m) const {
  int best = -1;
  double best_gap = max_gap_m;
  for (const Rock& r : rocks_) {
    if (r.height < min_height_m) continue;
    const double gap = (r.center - enu).norm() - r.a;
    if (gap < best_gap) {
      best_gap = gap;
      best = r.id;
    }
  }
  return best;
}

}  // namespace areomap
