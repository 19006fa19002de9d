// The synthetic Mars scene of the mission generator: an analytic terrain (fractal background,
// craters, rocks) with an albedo texture, evaluated at any point, so every product (orbital DTM,
// orthoimage, rover views) samples the same truth at its own resolution.
//
// Frame: local ENU at the scene origin (x east, y north [m]); heights z are metres above the
// body's ellipsoid (flat-earth approximation inside the scene: a few km at most).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace areomap {

// A fresh simple crater (ch. 2.1-2.3.1): raised rim, wall of nearly constant slope, bowl or flat
// floor. The rim crest is the ellipse (center, semi_major, semi_minor, angle).
struct Crater {
  int id = 0;
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // ENU [m].
  double semi_major = 0.0;                           // Rim crest [m].
  double semi_minor = 0.0;                           // Rim crest [m].
  double angle = 0.0;                                // Major axis from east toward north [rad].
  double depth = 0.0;                                // Rim crest to lowest floor point [m].
  double rim_height = 0.0;                           // Rim crest above the surroundings [m].
  double floor_fraction = 0.0;                       // Floor radius / rim radius (0 = bowl).
  bool flat_floor = false;
};

// Rock shapes of Appendix A (eqs. 2.5-2.9, A.1-A.3).
enum class RockShape { kHemispheroid, kSemiEllipsoid, kCone, kTetrahedron };
std::string ToString(RockShape shape);
RockShape RockShapeFromString(std::string_view text);  // Throws areomap::Error.

struct Rock {
  int id = 0;
  RockShape shape = RockShape::kHemispheroid;
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  // ENU [m].
  double height = 0.0;                               // Peak above the local ground [m].
  double a = 0.0;         // Radius, or semi-major axis of the semi-ellipsoid [m].
  double b = 0.0;         // Semi-minor axis of the semi-ellipsoid (= a otherwise) [m].
  double azimuth = 0.0;   // Rotation about the vertical: a axis / triangle vertex [rad].
  double tilt_x = 0.0;    // alpha: rotation about x [rad] (complex model, eq. 2.10).
  double tilt_y = 0.0;    // beta: rotation about y [rad].
  double ground_z = 0.0;  // Terrain height under the rock centre, without the rock [m].

  // Height of the rock surface above its base plane at (x, y) [m], 0 outside its footprint.
  double HeightAbove(const Eigen::Vector2d& p) const;
  double FootprintRadius() const;  // Radius of a circle holding the whole footprint [m].
};

struct SceneOptions {
  double half_extent_m = 256.0;          // Scene covers [-half, half]^2 [m].
  double base_elevation_m = -1900.0;     // Mean height above the ellipsoid [m].
  double roughness_m = 1.0;              // RMS of the fractal background [m].
  double roughness_wavelength_m = 60.0;  // Longest background wavelength [m].
  int crater_count = 12;                 // Craters besides the explicit ones.
  double crater_min_diameter_m = 8.0;    // Table 2.2 range.
  double crater_max_diameter_m = 120.0;
  // Degradation of the random craters, in [0, 0.9]: each draws g in [0, max] (none drawn at 0),
  // its depth shrinks by (1 - g), its rim by (1 - g)^2 (rims erode first) and a floor fills in
  // (flat, g of the rim radius, from g > 0.3). 0: fresh craters only.
  double crater_max_degradation = 0.0;
  // Random craters' centres lie at least this times the sum of their radii apart; under 1 they
  // overlap (their reliefs add). In [0.5, 3].
  double crater_min_spacing = 1.3;
  std::vector<Crater> explicit_craters;  // E.g. a Victoria-sized crater for a preset.
  // Rocks: Golombek & Rapp (1997) F(D) = k exp(-q D), q = 1.79 + 0.152 / k, placed within
  // `rock_corridor_m` of the polyline `rock_path` (the traverse). More than `max_rocks` at that
  // density throws areomap::Error (a cap would thin them below k).
  double rock_abundance_k = 0.05;
  double rock_min_diameter_m = 0.12;
  double rock_max_diameter_m = 1.2;
  double rock_max_tilt_deg = 20.0;
  double rock_corridor_m = 35.0;
  int max_rocks = 20000;
  std::vector<Eigen::Vector2d> rock_path;
  uint32_t seed = 1;

  void Check() const;  // Throws areomap::Error naming the field.
};

class Scene {
 public:
  explicit Scene(const SceneOptions& options);

  // Terrain height [m above ellipsoid] at ENU (x, y), rocks included.
  double HeightAt(double x, double y) const;
  // Height without rocks (the ground the rocks sit on).
  double GroundHeightAt(double x, double y) const;
  // Lambertian albedo in [0.05, 0.6].
  double AlbedoAt(double x, double y) const;
  // Unit surface normal by central differences over `step` [m].
  Eigen::Vector3d NormalAt(double x, double y, double step) const;

  const std::vector<Crater>& craters() const { return craters_; }
  const std::vector<Rock>& rocks() const { return rocks_; }
  // Id of the rock whose footprint edge is nearest to `enu` [m] (gap = centre distance - a,
  // negative inside), among rocks at least `min_height_m` high, when that gap is below
  // `max_gap_m`; -1 otherwise. Truth for "which rock is this peak on".
  int RockNear(const Eigen::Vector2d& enu, double min_height_m, double max_gap_m) const;
  const SceneOptions& options() const { return options_; }

 private:
  double Background(double x, double y) const;
  double CraterRelief(double x, double y) const;
  double RockRelief(double x, double y) const;

  SceneOptions options_;
  std::vector<Crater> craters_;
  std::vector<Rock> rocks_;
  // Uniform grid of rock indices for fast look-up.
  double rock_cell_m_ = 2.0;
  int rock_grid_n_ = 0;
  std::vector<std::vector<int>> rock_grid_;
  uint32_t noise_seed_ = 0;
};

}  // namespace areomap
