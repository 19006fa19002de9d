// Generated crater scenes for training the crater network (scripts/crater_model/train.py
// --generated DIR): orbital images rendered by the mission generator (fractal terrain, fresh bowl
// and flat-floored craters with raised rims; with --degraded-share also degraded ones, shallower
// with eroded rims and filled floors, and overlapping craters; Lambertian shading with cast
// shadows, MTF, noise, 10-bit) with every crater's rim as truth. They add what the CTX catalogue
// has little of: crisp, strongly shaded craters on rough ground under every sun, with complete
// labels.
//
// Run: build/release/eval/areomap_crater_training_scenes --out DIR [--count N] [--size PX]
//        [--seed N] [--degraded-share S]
// Writes DIR/scene-NNN.png (16-bit DN) and DIR/scene-NNN_craters.csv (x_px, y_px, diameter_px,
// annotators; pixel centres at +0.5 as the CTX labels, diameter = 2 sqrt(a b) of the rim crest,
// annotators = 6: every crater is certain). Each scene draws its GSD, crater density and sizes,
// terrain roughness and sun from the seed, so the set is the same on every machine.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include <CLI/CLI.hpp>
#include <opencv2/core.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/image_io.h"
#include "crater_scene.h"

namespace {

// One scene's random draw; sizes are drawn in pixels of the image and converted to metres by its
// GSD.
struct SceneDraw {
  areomap::SceneOptions scene;
  areomap::OrbitalImageOptions image;
  double dtm_posting_m = 0.0;
};

SceneDraw DrawScene(std::mt19937& rng, int size_px, double degraded_share) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const auto log_uniform = [&](double lo, double hi) {
    return std::exp(std::log(lo) + unit(rng) * (std::log(hi) - std::log(lo)));
  };
  SceneDraw d;
  areomap::OrbitalImageOptions& image = d.image;
  areomap::SceneOptions& scene = d.scene;
  image.gsd_m = log_uniform(0.25, 2.0);
  image.sun_azimuth_deg = 360.0 * unit(rng);
  image.sun_elevation_deg = 12.0 + 38.0 * unit(rng);
  image.mtf_sigma_px = 0.3 + 0.6 * unit(rng);
  image.read_noise_dn = 0.5 + 3.0 * unit(rng);
  image.ambient = 0.05 + 0.15 * unit(rng);
  image.seed = static_cast<uint32_t>(rng());
  image.supersample = 2;
  scene.half_extent_m = 0.5 * size_px * image.gsd_m;
  scene.crater_min_diameter_m = 5.0 * image.gsd_m;
  scene.crater_max_diameter_m = log_uniform(40.0, 120.0) * image.gsd_m;
  scene.crater_count =
      static_cast<int>(log_uniform(25.0, 160.0) * (size_px / 512.0) * (size_px / 512.0));
  scene.roughness_m = log_uniform(0.05, 0.6) * 10.0 * image.gsd_m;
  scene.roughness_wavelength_m = log_uniform(10.0, 80.0) * image.gsd_m;
  // No rock_path: the scene has no rocks.
  scene.seed = static_cast<uint32_t>(rng());
  d.dtm_posting_m = 8.0 * image.gsd_m;
  if (degraded_share > 0.0) {
    // Older surfaces: degraded craters beside fresh ones, craters that may overlap. Drawn only
    // when asked for, so that the default set stays the one the built-in model was trained on.
    const bool degraded = unit(rng) >= 1.0 - degraded_share;
    scene.crater_max_degradation = degraded ? 0.3 + 0.55 * unit(rng) : 0.0;
    scene.crater_min_spacing = 0.7 + 0.6 * unit(rng);
  }
  return d;
}

void WriteLabels(const std::filesystem::path& path, const std::vector<areomap::Ellipse>& craters,
                 int size_px) {
  std::string text = "x_px,y_px,diameter_px,annotators\n";
  char row[128];
  for (const areomap::Ellipse& e : craters) {
    const double d = 2.0 * std::sqrt(e.semi_major * e.semi_minor);
    // Rims wholly or partly inside the image; the sampler crops further.
    if (e.center.x() < -0.5 * d || e.center.y() < -0.5 * d || e.center.x() > size_px + 0.5 * d ||
        e.center.y() > size_px + 0.5 * d) {
      continue;
    }
    std::snprintf(row, sizeof(row), "%.3f,%.3f,%.3f,6\n", e.center.x(), e.center.y(), d);
    text += row;
  }
  areomap::WriteFileAtomically(path, text);
}

}  // namespace

int main(int argc, char** argv) {
  std::filesystem::path out;
  int count = 64, size_px = 512;
  uint32_t seed = 11;
  double degraded_share = 0.0;
  CLI::App app{"Generated crater scenes for training the crater network"};
  app.add_option("--out", out, "Folder for scene-NNN.png and scene-NNN_craters.csv")->required();
  app.add_option("--count", count, "Number of scenes")->check(CLI::Range(1, 100000));
  app.add_option("--size", size_px, "Image side [px]")->check(CLI::Range(64, 16384));
  app.add_option("--seed", seed, "Seed of every random draw");
  app.add_option("--degraded-share", degraded_share,
                 "Share of the scenes with degraded craters; above 0 craters may also overlap")
      ->check(CLI::Range(0.0, 1.0));
  CLI11_PARSE(app, argc, argv);
  std::filesystem::create_directories(out);
  std::mt19937 rng(seed);
  for (int i = 0; i < count; ++i) {
    const SceneDraw d = DrawScene(rng, size_px, degraded_share);
    const areomap::testing::CraterScene s =
        areomap::testing::MakeCraterScene(d.scene, d.image, d.dtm_posting_m);
    char stem[32];
    std::snprintf(stem, sizeof(stem), "scene-%03d", i);
    areomap::WriteImage(out / (std::string(stem) + ".png"), s.products.image.bands.at(0));
    WriteLabels(out / (std::string(stem) + "_craters.csv"), s.truth_px, size_px);
    std::printf("%s: gsd %.2f m, %zu craters, sun %.0f/%.0f deg\n", stem, d.image.gsd_m,
                s.truth_px.size(), d.image.sun_azimuth_deg, d.image.sun_elevation_deg);
  }
  return 0;
}
