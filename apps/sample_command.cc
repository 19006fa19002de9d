// areomap sample --out DIR: writes the built-in georeferenced Mars sample terrain.
#include <iostream>

#include "areomap/map/raster.h"
#include "areomap/samples/sample_terrain.h"
#include "commands.h"

namespace areomap::cli {

// What `areomap sample --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kSampleDetails =
    "Writes a single small DTM GeoTIFF with one crater (`--seed`, `--size`, `--posting`, `--lat`,\n"
    "`--lon`, `--crater-diameter`): a fixture for raster and CRS work.";

void AddSampleCommand(CLI::App& app, const GlobalOptions& global) {
  auto options = std::make_shared<SampleTerrainOptions>();
  auto out_dir = std::make_shared<std::string>();
  auto* cmd = app.add_subcommand(
      "sample", "Write the built-in sample: a small Mars DTM GeoTIFF with one fresh crater");
  cmd->footer(kSampleDetails);
  cmd->add_option("--out", *out_dir, "Output folder (created if needed)")->required();
  auto* group = cmd->add_option_group("Terrain");
  group->add_option("--seed", options->seed, "Seed of the background relief")
      ->check(IntegerIn(0, 4294967295))  // 32 bits
      ->capture_default_str();
  group->add_option("--size", options->size_px, "Tile edge [px]")
      ->check(IntegerIn(16, 8192))
      ->capture_default_str();
  group->add_option("--posting", options->posting_m, "Pixel size [m]")
      ->check(NumberIn(0.0, 1000.0, Bound::kOpen))
      ->capture_default_str();
  // Not at the poles: the terrain is an equirectangular tile.
  group->add_option("--lat", options->center_lat_deg, "Centre planetocentric latitude [deg]")
      ->check(NumberIn(-85.0, 85.0, Bound::kOpen, Bound::kOpen))
      ->capture_default_str();
  group->add_option("--lon", options->center_lon_deg, "Centre east longitude [deg]")
      ->check(Longitude())
      ->capture_default_str();
  group->add_option("--crater-diameter", options->crater_diameter_m, "Crater diameter [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->callback([options, out_dir, &global] {
    options->Check();
    OutputFolder out(*out_dir, OutputPolicy(global, "sample", {"sample_dtm.tif"}, {}));
    const ProgressCallback progress = MakeProgressBar(global, "sample");
    progress(0.0, "terrain");
    const GeoRaster dtm = MakeSampleTerrain(*options);
    progress(0.6, "GeoTIFF");
    WriteGeoTiff(out / "sample_dtm.tif", dtm);
    const std::filesystem::path dtm_path = out.final_dir() / "sample_dtm.tif";
    double min_z = 0.0, max_z = 0.0;
    cv::minMaxLoc(dtm.bands.front(), &min_z, &max_z);
    WriteSummary(out.dir(), {{"command", "sample"},
                             {"dtm", dtm_path.filename().string()},
                             {"size_px", options->size_px},
                             {"posting_m", options->posting_m},
                             {"center_lat_deg", options->center_lat_deg},
                             {"center_lon_deg", options->center_lon_deg},
                             {"crater_diameter_m", options->crater_diameter_m},
                             {"seed", options->seed},
                             {"min_elevation_m", min_z},
                             {"max_elevation_m", max_z}});
    out.Commit();
    progress(1.0, "done");
    if (!global.quiet) {
      std::cout << "wrote " << dtm_path.string() << " (" << options->size_px << " x "
                << options->size_px << " px at " << options->posting_m << " m, elevation " << min_z
                << " .. " << max_z << " m)\n";
    }
  });
}

}  // namespace areomap::cli
