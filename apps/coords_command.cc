// areomap coords --from A --to B: converts points read one per line on stdin.
#include <cstdio>
#include <iostream>
#include <string>

#include "areomap/map/coordinate_system.h"
#include "areomap/map/error.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct CoordsOptions {
  std::string from;
  std::string to;
  std::string body = "mars2000";
  std::string origin;  // "LAT,LON[,H]", planetocentric degrees and metres.
};

std::optional<Geographic> ParseOrigin(const std::string& text) {
  if (text.empty()) return std::nullopt;
  Eigen::Vector3d v;
  try {
    v = ParsePointLine(text);
  } catch (const Error& e) {
    throw Error("--origin '" + text + "': " + e.what() + ": expected LAT,LON[,H]");
  }
  if (!v.allFinite()) throw Error("--origin '" + text + "': expected finite numbers LAT,LON[,H]");
  if (std::abs(v.x()) > 90.0) {
    throw Error("--origin latitude " + std::to_string(v.x()) + " is outside [-90, 90] degrees");
  }
  if (std::abs(v.y()) > 360.0) {
    throw Error("--origin longitude " + std::to_string(v.y()) + " is outside [-360, 360] degrees");
  }
  return Geographic{RadFromDeg(v.x()), RadFromDeg(v.y()), v.z()};
}

int RunCoords(const CoordsOptions& options, bool body_given) {
  CoordinateSystemContext context;
  context.body = Body::FromName(options.body);
  context.origin = ParseOrigin(options.origin);
  const CoordinateConversion conversion =
      CoordinateConversion::Make(options.from, options.to, context, body_given);
  if (conversion.datum_body) {
    std::fprintf(stderr,
                 "note: geographic and local coordinates on the datum of %s (a = %.0f m, b = %.0f "
                 "m); --body mars2000 puts them on the IAU 2000 ellipsoid\n",
                 conversion.datum_source.c_str(), conversion.datum_body->a,
                 conversion.datum_body->b);
  }
  const CoordinateSystem& to = conversion.to;
  std::string line;
  int line_number = 0;
  int failures = 0;
  while (std::getline(std::cin, line)) {
    ++line_number;
    if (PointLineIsEmpty(line)) continue;
    try {
      const Eigen::Vector3d out = conversion.Convert(ParsePointLine(line));
      std::printf("%.*f %.*f %.*f\n", to.Decimals(0), out.x(), to.Decimals(1), out.y(),
                  to.Decimals(2), out.z());
    } catch (const Error& e) {
      ++failures;
      std::printf("nan nan nan\n");
      std::fprintf(stderr, "error: stdin line %d: %s\n", line_number, e.what());
    }
    std::fflush(stdout);
  }
  return failures == 0 ? 0 : 1;
}

}  // namespace

// What `areomap coords --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kCoordsDetails =
    "Converts points read one per line on stdin (GeographicLib-style). Systems: `mbf` (X Y Z m),\n"
    "`planetocentric[,west][,360]` and `planetographic[,west][,360]` (lat lon [h]), `spherical`\n"
    "(lat lon radius), `enu` and `site` (MER site frame: X north, Y east, Z down; need `--origin\n"
    "LAT,LON[,H]`), `raster:FILE` (map x y of a raster's CRS), `pixel:FILE` (col row, pixel "
    "centres\n"
    "at +0.5), or any CRS GDAL/PROJ knows such as `IAU_2015:49910` (x/longitude first). `--body\n"
    "mars2000|mars-sphere|mola-sphere`; without it, latitudes and heights are on the datum of the\n"
    "raster or CRS on the other side (as `info` lists a raster's corners; a note on stderr says\n"
    "so), else on the IAU 2000 ellipsoid. Every conversion goes through body-fixed XYZ, so a "
    "point\n"
    "keeps its place in space: from a sphere-based CRS to an ellipsoid-based one (e.g.\n"
    "`IAU_2015:49910` to `49911`) the latitude and height change as the geometry demands, where\n"
    "PROJ's `cs2cs` keeps the numbers of latitude and longitude (a \"ballpark\" change of datum) "
    "and\n"
    "differs from areomap by up to ~20 km in planetographic latitude. A bad line prints `nan nan\n"
    "nan`, an error naming the line, and the exit status is 1; the other lines are converted.";

void AddCoordsCommand(CLI::App& app, const GlobalOptions& /*global*/) {
  auto options = std::make_shared<CoordsOptions>();
  auto* cmd = app.add_subcommand(
      "coords",
      "Convert coordinates read one point per line on stdin (2 or 3 numbers per line).\n"
      "Systems: mbf (X Y Z m) | planetocentric[,west][,360] (lat lon [h], deg, m above the "
      "ellipsoid) | planetographic[,west][,360] | spherical (lat lon radius) | enu | site (MER "
      "site frame: X north, Y east, Z down; need --origin) | raster:FILE (map x y [h]) | "
      "pixel:FILE (col row [h], pixel centres at +0.5) | any CRS GDAL knows, e.g. "
      "IAU_2015:49910 (x/lon first)");
  cmd->footer(kCoordsDetails);
  cmd->add_option("--from", options->from, "Input coordinate system")->required();
  cmd->add_option("--to", options->to, "Output coordinate system")->required();
  CLI::Option* body =
      cmd->add_option("--body", options->body,
                      "Body of the geographic and local systems: mars2000 (IAU 2000 ellipsoid "
                      "3396190/3376200 m), mars-sphere (3396190 m), mola-sphere (3396000 m); "
                      "default: the datum of a raster:, pixel: or CRS system on the other side, "
                      "else mars2000");
  cmd->add_option("--origin", options->origin,
                  "Origin of enu/site frames: LAT,LON[,H] in planetocentric degrees east, "
                  "metres above the ellipsoid");
  cmd->callback([options, body] {
    const int status = RunCoords(*options, body->count() > 0);
    if (status != 0) throw CLI::RuntimeError(status);
  });
}

}  // namespace areomap::cli
