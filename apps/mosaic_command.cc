// areomap mosaic ORTHO.tif... --out DIR: per-site orthophotos blended into one orthomosaic with
// feathered seams (mosaic.tif: image, valid mask, resolution map, source id; Mars CRS, nodata).
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "areomap/map/crs.h"
#include "areomap/map/error.h"
#include "areomap/map/mosaic.h"
#include "commands.h"

namespace areomap::cli {

// What `areomap mosaic --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kMosaicDetails =
    "Blends per-site orthophotos into `mosaic.tif` with feathered seams (`--feather` m), keeping\n"
    "mask, resolution and source id.";

void AddMosaicCommand(CLI::App& app, const GlobalOptions& global) {
  auto inputs = std::make_shared<std::vector<std::string>>();
  auto out_dir = std::make_shared<std::string>();
  auto options = std::make_shared<MosaicOptions>();
  auto* cmd = app.add_subcommand(
      "mosaic", "Blend per-site orthophotos (areomap ortho) into one orthomosaic, feathered seams");
  cmd->footer(kMosaicDetails);
  cmd->add_option("orthophotos", *inputs, "Orthophoto GeoTIFFs on one grid (areomap ortho)")
      ->required();
  cmd->add_option("--out", *out_dir, "Output folder (created if needed)")->required();
  cmd->add_option("--feather", options->feather_m, "Blend width at seams [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->callback([inputs, out_dir, options, &global] {
    options->Check();
    OutputFolder out(
        *out_dir, OutputPolicy(global, "mosaic", {"mosaic.tif"}, {inputs->begin(), inputs->end()}));
    const ProgressCallback progress = MakeProgressBar(global, "mosaic");
    // Each input is read only over its painted cells (its valid band scanned in strips first):
    // memory by what is painted, not by the raster; an input with none adds nothing.
    std::vector<Orthophoto> orthophotos;
    std::string first;  // The first input kept.
    for (const std::string& path : *inputs) {
      const std::optional<GridSpec> painted = OrthophotoValidWindow(path);
      if (!painted) {
        std::fprintf(stderr,
                     "warning: %s: no painted cell (band 'valid' is 0 everywhere); left out\n",
                     path.c_str());
        continue;
      }
      orthophotos.push_back(ReadOrthophoto(path, *painted));
      if (first.empty()) first = path;
      const Orthophoto& o = orthophotos.back();
      Crs::FromWkt(o.crs_wkt, path).RequireMars();
      if (o.crs_wkt != orthophotos.front().crs_wkt) {
        throw Error(path + ": its CRS differs from " + first + "'s");
      }
    }
    if (orthophotos.empty()) {
      throw Error(
          "no input orthophoto has a painted cell (band 'valid' is 0 everywhere): "
          "nothing to blend");
    }
    const GridSpec grid = CommonGrid(orthophotos);
    const Orthophoto mosaic =
        MakeOrthomosaic(orthophotos, grid, orthophotos.front().crs_wkt, *options, progress);
    WriteOrthophoto(out / "mosaic.tif", mosaic);
    const std::filesystem::path path = out.final_dir() / "mosaic.tif";
    WriteSummary(out.dir(), {{"command", "mosaic"},
                             {"mosaic", path.filename().string()},
                             {"inputs", *inputs},
                             {"width", grid.width},
                             {"height", grid.height},
                             {"posting_m", grid.posting},
                             {"feather_m", options->feather_m},
                             {"valid_cells", mosaic.valid_cells},
                             {"coverage", static_cast<double>(mosaic.valid_cells) /
                                              (static_cast<double>(grid.width) * grid.height)}});
    out.Commit();
    if (!global.quiet) {
      std::cout << "wrote " << path.string() << " (" << grid.width << " x " << grid.height << " at "
                << grid.posting << " m, " << mosaic.valid_cells << " valid cells)\n";
    }
  });
}

}  // namespace areomap::cli
