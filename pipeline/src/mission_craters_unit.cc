// The crater stage of a mission run (craters/): rims detected on the mission's first orbital
// image (the sun azimuth from the manifest, else estimated from the image, enables the shading
// checks), the catalogue as CSV, JSON and GeoPackage, an overlay PNG, and the score against the
// generator's truth/craters.csv.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "areomap/crater/crater_output.h"
#include "areomap/crater/crater_raster.h"
#include "areomap/crater/crater_score.h"
#include "areomap/crater/sun_azimuth.h"
#include "areomap/map/csv.h"
#include "areomap/map/error.h"
#include "mission_units.h"

namespace areomap::mission_run {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// truth/craters.csv (docs/mission-format.md): centres col_px, row_px in the orbital image's
// pixels (GDAL convention) and semi-axes [m]; rim diameter a + b in pixels of `pixel_size_m`.
std::vector<CraterCircle> ReadTruthCraters(const fs::path& path, double pixel_size_m) {
  std::ifstream in(path);
  if (!in) throw Error(path.string() + ": cannot open the truth crater table");
  std::string line;
  std::getline(in, line);
  std::map<std::string, size_t> column;
  const std::vector<std::string> header = SplitCsvLine(line);
  for (size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  for (const char* name : {"col_px", "row_px", "semi_major_m", "semi_minor_m"}) {
    if (!column.contains(name)) {
      throw Error(path.string() + ": expected a column \"" + name + "\" in the header");
    }
  }
  std::vector<CraterCircle> truth;
  for (int number = 2; std::getline(in, line); ++number) {
    if (line.empty()) continue;
    const std::vector<std::string> fields = SplitCsvLine(line);
    const auto value = [&](const char* name) {
      const size_t index = column.at(name);
      try {
        if (index < fields.size()) return std::stod(fields[index]);
      } catch (const std::exception&) {
      }
      throw Error(path.string() + ":" + std::to_string(number) + ": expected a number in column " +
                  name);
    };
    truth.push_back({{value("col_px"), value("row_px")},
                     (value("semi_major_m") + value("semi_minor_m")) / pixel_size_m});
  }
  return truth;
}

}  // namespace

CratersUnitResult DetectOrbitalCraters(const MissionRunContext& run,
                                       const ProgressCallback& progress) {
  CratersUnitResult summary;
  const MissionOrbitalProduct* image = run.mission->FirstOrbital("image");
  if (image == nullptr) {
    summary.skipped = true;
    summary.reason = "the mission has no orbital image";
    return summary;
  }
  const fs::path dir = run.out_dir / "craters";
  fs::create_directories(dir);
  const RasterDataset dataset = RasterDataset::Open(image->path);
  const RasterInfo& info = dataset.info();
  const CraterCatalog probe = MakeCraterCatalog({}, info);
  if (!(probe.pixel_size_m > 0.0)) {
    throw Error(image->path.string() + ": crater detection needs a projected Mars CRS");
  }
  CraterDetectorOptions options = run.options->craters;
  options.min_diameter_px = run.options->crater_min_diameter_m / probe.pixel_size_m;
  options.sun_azimuth_deg = image->sun_azimuth_deg;  // North-up: clockwise from image up.
  options.Check();
  // A manifest without the image's sun: estimated from its craters' shading (sun_azimuth.h) for
  // the edge detector (alone or combined with the network); the network alone needs none.
  summary.sun_azimuth_source = options.sun_azimuth_deg ? "manifest" : "none";
  if (!options.sun_azimuth_deg && options.method != CraterMethod::kLearned) {
    const SunAzimuthEstimate e = EstimateSunAzimuthInRaster(dataset, options);
    summary.sun_azimuth_source = e.reliable ? "estimated" : "none";
    summary.sun_azimuth_estimate = SunAzimuthEstimateJson(e);
    if (e.reliable) options.sun_azimuth_deg = e.azimuth_deg;
  }
  summary.sun_azimuth_deg = options.sun_azimuth_deg;
  const std::vector<CraterDetection> found =
      DetectCratersInRaster(dataset, RimSource::kImage, options, progress);
  const CraterCatalog catalog = MakeCraterCatalog(found, info);
  WriteCratersCsv(dir / "craters.csv", catalog);
  WriteCratersJson(dir / "craters.json", catalog);
  WriteCratersGeoPackage(dir / "craters.gpkg", catalog);
  const int factor = DecimationFactor(info.width, info.height, 2048);
  WriteCraterOverlay(dir / "overlay.png", ReadDecimated(dataset, dataset.FullWindow(), factor),
                     found, 2048);

  summary.image = image->path.filename().string();
  summary.pixel_size_m = probe.pixel_size_m;
  summary.min_diameter_m = run.options->crater_min_diameter_m;
  summary.method = ToString(options.method);
  summary.craters = static_cast<int64_t>(found.size());
  summary.files = {"craters.csv", "craters.json", "craters.gpkg", "overlay.png"};
  if (run.mission->truth_craters_csv) {
    const std::vector<CraterCircle> truth =
        ReadTruthCraters(*run.mission->truth_craters_csv, probe.pixel_size_m);
    const double lo = options.min_diameter_px;
    const CraterScore score = ScoreCraters(truth, CirclesOf(found),
                                           {lo, 4 * lo, std::numeric_limits<double>::infinity()});
    json record = CraterMatchStatsJson(score.all);
    record["rule"] =
        "centre distance < 0.5 x truth radius and detected/true diameter in [0.7, 1.3]";
    summary.score = CraterScoreRecord::FromJson(record, "craters score");
  }
  return summary;
}

}  // namespace areomap::mission_run
