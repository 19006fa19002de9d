// areomap craters IMAGE|DTM --out DIR: crater rims, ellipses and models; areomap craters score.
#include <cmath>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "areomap/crater/crater_output.h"
#include "areomap/crater/crater_raster.h"
#include "areomap/crater/crater_score.h"
#include "areomap/crater/learned_detector.h"
#include "areomap/crater/sun_azimuth.h"
#include "areomap/map/error.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct CratersArgs {
  std::string input;
  std::string out_dir;
  bool dtm = false;
  std::string units = "px";
  double min_diameter = 8.0;
  double max_diameter = 0.0;
  std::optional<double> sun_azimuth_deg;
  bool estimate_sun = true;
  std::string method = "combined";
  CraterDetectorOptions detector;
};

// The sun azimuth the detector uses: --sun-azimuth, else (an image) estimated from the shading of
// craters found without it; `json` records which and how. Throws when --shading-templates are
// asked for and no sun is known.
std::optional<double> ChooseSunAzimuth(const CratersArgs& a, const RasterDataset& dataset,
                                       const CraterDetectorOptions& options,
                                       const GlobalOptions& global, nlohmann::json* json) {
  if (a.dtm) {
    (*json)["sun_azimuth_source"] = "none (DTM)";
    return std::nullopt;
  }
  if (a.sun_azimuth_deg) {
    (*json)["sun_azimuth_source"] = "given";
    return a.sun_azimuth_deg;
  }
  (*json)["sun_azimuth_source"] = "none";
  // The learned detector needs no sun: its rim fits run without the shading checks.
  if (options.method == CraterMethod::kLearned) return std::nullopt;
  if (!a.estimate_sun) {
    if (options.shading_template.enabled) {
      throw Error(
          "craters: --shading-templates needs a sun azimuth: give --sun-azimuth, or "
          "drop --no-sun-estimate");
    }
    return std::nullopt;
  }
  const SunAzimuthEstimate e =
      EstimateSunAzimuthInRaster(dataset, options, {}, MakeProgressBar(global, "sun azimuth"));
  (*json)["sun_azimuth_estimate"] = SunAzimuthEstimateJson(e);
  std::ostringstream text;
  text << std::fixed << std::setprecision(0) << e.votes << " of " << e.candidates
       << " craters found without a sun show a bright and a dark wall; " << std::setprecision(2)
       << e.agreement << " of them agree";
  if (!e.reliable) {
    if (options.shading_template.enabled) {
      throw Error(
          "craters: --shading-templates needs a sun azimuth: give --sun-azimuth (the "
          "estimate from " +
          a.input + " is not reliable: " + text.str() + ")");
    }
    std::cerr << "warning: no sun azimuth given and none could be estimated from " << a.input
              << " (" << text.str() << "): the shading checks are off, expect more false "
              << "detections (nested rims, mounds); give --sun-azimuth\n";
    return std::nullopt;
  }
  (*json)["sun_azimuth_source"] = "estimated";
  if (!global.quiet) {
    std::cout << "sun azimuth estimated from the image: " << std::fixed << std::setprecision(1)
              << e.azimuth_deg << " deg (" << text.str() << ")\n";
  }
  return e.azimuth_deg;
}

void RunDetect(const CratersArgs& a, const GlobalOptions& global) {
  const RasterDataset dataset = RasterDataset::Open(a.input);
  const RasterInfo& info = dataset.info();
  CraterDetectorOptions options = a.detector;
  options.method = a.dtm ? CraterMethod::kEdges : CraterMethodFromString(a.method);
  // Ground size of a pixel, to turn metres into pixels and DTM heights into slopes.
  const CraterCatalog probe = MakeCraterCatalog({}, info);
  if (a.units == "m" && !(probe.pixel_size_m > 0.0)) {
    throw Error(a.input + ": --units m needs a georeferenced raster in a projected Mars CRS " +
                "(this one has no geotransform or CRS); give diameters in px");
  }
  const double to_px = a.units == "m" ? 1.0 / probe.pixel_size_m : 1.0;
  options.min_diameter_px = a.min_diameter * to_px;
  options.max_diameter_px = a.max_diameter * to_px;
  if (!(options.min_diameter_px >= CraterDetectorOptions::kSmallestDiameterPx)) {
    std::ostringstream text;
    text << "--min-diameter: " << a.min_diameter;
    if (a.units == "m") {
      text << " m (" << options.min_diameter_px << " px of " << probe.pixel_size_m << " m on "
           << a.input << ")";
    } else {
      text << " px";
    }
    text << " is below the smallest rim diameter detected, "
         << CraterDetectorOptions::kSmallestDiameterPx << " px";
    throw Error(text.str());
  }
  const double posting = probe.pixel_size_m > 0.0 ? probe.pixel_size_m : 1.0;
  options.dtm_posting = posting;
  options.Check();
  // A missing or unreadable model is reported before any work or output.
  if (options.method != CraterMethod::kEdges) CraterNetwork{options.learned.model_path};
  nlohmann::json sun_json;
  options.sun_azimuth_deg = ChooseSunAzimuth(a, dataset, options, global, &sun_json);
  OutputFolder folder(
      a.out_dir,
      OutputPolicy(global, "craters",
                   {"craters.csv", "craters.json", "craters.gpkg", "overlay.png"}, {a.input}));
  const RimSource source = a.dtm ? RimSource::kDtm : RimSource::kImage;
  const ProgressCallback progress = MakeProgressBar(global, "craters");
  const std::vector<CraterDetection> found =
      DetectCratersInRaster(dataset, source, options, progress);
  CraterCatalog catalog = MakeCraterCatalog(found, info);
  if (a.dtm) {
    for (CatalogCrater& c : catalog.craters) {
      const Ellipse& e = c.detection.ellipse;
      const double reach = 1.2 * e.semi_major + 4.0;
      const int c0 = std::max(0, static_cast<int>(e.center.x() - reach));
      const int r0 = std::max(0, static_cast<int>(e.center.y() - reach));
      const int c1 = std::min(info.width, static_cast<int>(e.center.x() + reach) + 1);
      const int r1 = std::min(info.height, static_cast<int>(e.center.y() + reach) + 1);
      if (c1 <= c0 || r1 <= r0) continue;
      Ellipse local = e;
      local.center -= Eigen::Vector2d(c0, r0);
      c.model = MeasureCraterOnDtm(dataset.ReadWindowFloat(1, {c0, r0, c1 - c0, r1 - r0}), local,
                                   posting);
    }
  }
  const std::filesystem::path out = folder.dir();
  WriteCratersCsv(out / "craters.csv", catalog);
  WriteCratersJson(out / "craters.json", catalog);
  nlohmann::json files = {"craters.csv", "craters.json", "overlay.png"};
  if (catalog.IsGeoreferenced()) {
    WriteCratersGeoPackage(out / "craters.gpkg", catalog);
    files.push_back("craters.gpkg");
  }
  const int factor = DecimationFactor(info.width, info.height, 4096);
  int64_t valid_pixels = 0;
  WriteCraterOverlay(out / "overlay.png",
                     ReadDecimated(dataset, dataset.FullWindow(), factor, &valid_pixels), found,
                     4096);
  int partial = 0, rims_fitted = 0, edge_detected = 0;
  for (const CraterDetection& d : found) {
    partial += d.partial ? 1 : 0;
    rims_fitted += d.rim_fitted ? 1 : 0;
    edge_detected += d.edge_detected ? 1 : 0;
  }
  nlohmann::json summary = {
      {"command", "craters"},
      {"input", a.input},
      {"source", a.dtm ? "dtm" : "image"},
      {"method", ToString(options.method)},
      {"model", options.method != CraterMethod::kEdges
                    ? (options.learned.model_path.empty() ? std::string("built-in")
                                                          : options.learned.model_path)
                    : std::string()},
      {"rims_fitted", rims_fitted},
      {"edge_detected", edge_detected},
      {"width_px", info.width},
      {"height_px", info.height},
      {"georeferenced", catalog.IsGeoreferenced()},
      {"pixel_size_m", catalog.pixel_size_m},
      {"min_diameter_px", options.min_diameter_px},
      {"max_diameter_px", options.max_diameter_px},
      {"upsample_small_craters", options.upsample_small_craters},
      // whether that level was searched: only for minimum diameters under 16 px
      {"upsampled_level_searched", options.SearchesUpsampledLevel()},
      {"sun_azimuth_deg",
       options.sun_azimuth_deg ? nlohmann::json(*options.sun_azimuth_deg) : nlohmann::json()},
      {"valid_pixels", valid_pixels},
      {"craters", found.size()},
      {"partial", partial},
      {"files", files}};
  summary.update(sun_json);
  WriteSummary(out, summary);
  folder.Commit();  // Also removes an earlier run's craters.gpkg when this input has no CRS.
  if (valid_pixels == 0) {
    std::cerr << "warning: " << a.input
              << " has no valid pixel (every pixel is nodata or NaN): nothing was searched\n";
  }
  if (!global.quiet) {
    std::cout << "found " << found.size() << " craters (" << partial << " partial) in " << a.input
              << "; wrote " << a.out_dir << "\n";
  }
}

}  // namespace

// What `areomap craters --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kCratersDetails =
    "Crater rims as ellipses with 1σ. Images, default `--method combined`: both detectors below,\n"
    "every edge rim plus each crater only the network found (`edge_detected` 0), F1 0.73 on\n"
    "held-out CTX and 0.54 on HRSC against 0.32 and 0.44 for the edges alone. `--method edges`\n"
    "(DTMs always): sub-pixel Canny edges (curvature crests with `--dtm`), arcs, ellipse\n"
    "hypotheses, validation by edge support and the bowl's shading under the sun\n"
    "(`--sun-azimuth`, or estimated; `--no-sun-estimate`), a 2× upsampled level for craters under\n"
    "16 px (`--no-upsample`), `--shading-templates`; five times faster. `--method learned`: a\n"
    "small trained network (centre-point CNN on an image pyramid, OpenCV dnn, built in; `--model`\n"
    "loads another, `--min-score` its threshold) finds the craters and each rim is refitted as an\n"
    "ellipse where it shows edges (`rim_fitted` 1; else the network's circle, 0; `--no-rim-fit`);\n"
    "docs/crater-model.md. All: Ceres orthogonal-distance fits, tiles read in windows (bounded\n"
    "memory, TBB). Writes `craters.csv`, `craters.json`, `craters.gpkg` (Mars "
    "CRS,\n"
    "when georeferenced), `overlay.png`, `summary.json`. `craters score DETECTIONS.csv TRUTH.csv\n"
    "[--image IMAGE --out DIR]`: precision, recall, F1 by diameter bin. Speed and accuracy:\n"
    "docs/benchmarks.md (Craters).";

void AddCratersCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<CratersArgs>();
  auto* cmd = app.add_subcommand(
      "craters", "Detect crater rims in an image or DTM: ellipses, uncertainties, models");
  cmd->footer(kCratersDetails);
  cmd->require_subcommand(0, 1);
  cmd->add_option("input", args->input, "Image or DTM raster (GeoTIFF, PNG, ISIS3, PDS...)");
  cmd->add_option("--out", args->out_dir, "Output folder (created if needed)");
  cmd->add_flag("--dtm", args->dtm, "The input holds heights: rims from curvature crests");
  cmd->add_option("--method", args->method,
                  "Image detector: combined (both below, the network's finds added to the edge "
                  "rims), edges (rim edges to ellipses) or learned (trained network, rims "
                  "refitted as ellipses where they show edges; docs/crater-model.md). DTMs "
                  "always use edges")
      ->check(CLI::IsMember({"combined", "learned", "edges"}))
      ->capture_default_str();
  cmd->add_option("--model", args->detector.learned.model_path,
                  "learned, combined: ONNX crater model trained as the built-in one "
                  "(scripts/crater_model/train.py); default: built-in");
  cmd->add_option("--min-score", args->detector.learned.min_score,
                  "learned, combined: heat-map peak threshold in (0, 1)")
      ->check(NumberIn(0.0, 1.0, Bound::kOpen, Bound::kOpen))
      ->capture_default_str();
  cmd->add_flag("--no-rim-fit{false}", args->detector.learned.refine_rims,
                "learned, combined: keep the network's circles, do not refit rims as ellipses");
  cmd->add_option("--units", args->units, "Unit of the diameter limits: px or m")
      ->check(CLI::IsMember({"px", "m"}))
      ->capture_default_str();
  // At least 4 px, checked in px once --units and the raster's pixel size are known.
  cmd->add_option("--min-diameter", args->min_diameter, "Smallest rim diameter (at least 4 px)")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--max-diameter", args->max_diameter, "Largest rim diameter (0: no limit)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  cmd->add_option("--sun-azimuth", args->sun_azimuth_deg,
                  "Sun azimuth [deg clockwise from image up]: enables the shading checks")
      ->check(FiniteNumber());
  cmd->add_flag("!--no-sun-estimate", args->estimate_sun,
                "Without --sun-azimuth, do not estimate it from the shading of the image's craters "
                "(the shading checks stay off)");
  cmd->add_option("--tile-size", args->detector.tile_size, "Tile core edge [px]")
      ->check(IntegerAtLeast(256))
      ->capture_default_str();
  cmd->add_option("--tile-overlap", args->detector.tile_overlap,
                  "Tile margin [px] (at most --tile-size)")
      ->check(IntegerAtLeast(32))
      ->capture_default_str();
  cmd->add_option("--min-shading-contrast", args->detector.min_shading_contrast,
                  "Image with sun: wall contrast threshold")
      ->check(FiniteNumber())
      ->capture_default_str();
  cmd->add_option("--min-coverage", args->detector.min_coverage,
                  "Fraction of rim sectors that must hold edges")
      ->check(NumberIn(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--max-axis-ratio", args->detector.max_axis_ratio, "Largest a / b accepted")
      ->check(NumberAtLeast(1.0))
      ->capture_default_str();
  cmd->add_option("--min-edge-contrast", args->detector.min_edge_contrast,
                  "Rim edge strength / high Canny threshold")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  cmd->add_flag("--no-upsample{false}", args->detector.upsample_small_craters,
                "Skip the 2x upsampled level for craters under 16 px across (faster; finds fewer "
                "of them)");
  cmd->add_flag("--shading-templates", args->detector.shading_template.enabled,
                "Also seek small degraded bowls by their shading (needs a sun azimuth, given or "
                "estimated; ~1.35x time)");

  auto score_args = std::make_shared<std::array<std::string, 4>>();
  auto min_score_diameter = std::make_shared<double>(8.0);
  auto* score = cmd->add_subcommand(
      "score",
      "Precision, recall, F1 of detections against truth (CSV with x_px, y_px, diameter_px). "
      "Match: centre distance < 0.5 x truth radius and diameter ratio within +-30 %");
  score->add_option("detections", (*score_args)[0], "Detections CSV")->required();
  score->add_option("truth", (*score_args)[1], "Truth CSV")->required();
  score->add_option("--min-diameter", *min_score_diameter, "Smallest diameter scored [px] (0: all)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  score->add_option("--out", (*score_args)[2], "Also write DIR/summary.json");
  score->add_option("--image", (*score_args)[3],
                    "With --out: also write DIR/score_overlay.png on this image (truth green when "
                    "matched, red when missed; false alarms yellow)");
  score->callback([score_args, min_score_diameter, &global] {
    const std::vector<CraterCircle> detections = ReadCraterCsv((*score_args)[0]);
    const std::vector<CraterCircle> truth = ReadCraterCsv((*score_args)[1]);
    const double lo = *min_score_diameter;
    const double inf = std::numeric_limits<double>::infinity();
    const CraterScore s = ScoreCraters(truth, detections, {lo, 2 * lo, 4 * lo, 8 * lo, inf});
    nlohmann::json summary = {
        {"command", "craters score"},
        {"detections", (*score_args)[0]},
        {"truth", (*score_args)[1]},
        {"rule", "centre distance < 0.5 x truth radius and detected/true diameter in [0.7, 1.3]"},
        {"all", CraterMatchStatsJson(s.all)},
        {"bins", nlohmann::json::array()}};
    for (const auto& b : s.bins) summary["bins"].push_back(CraterMatchStatsJson(b));
    if (!(*score_args)[3].empty() && (*score_args)[2].empty()) {
      throw Error("craters score: --image needs --out DIR for the overlay");
    }
    if (!(*score_args)[2].empty()) {
      OutputFolder folder((*score_args)[2],
                          OutputPolicy(global, "craters score", {"score_overlay.png"},
                                       {(*score_args)[0], (*score_args)[1], (*score_args)[3]}));
      if (!(*score_args)[3].empty()) {
        const RasterDataset image = RasterDataset::Open((*score_args)[3]);
        WriteScoreOverlay(folder / "score_overlay.png",
                          image.ReadWindowFloat(1, image.FullWindow()), truth, detections, s, lo);
        summary["overlay"] = "score_overlay.png";
      }
      WriteSummary(folder.dir(), summary);
      folder.Commit();
    }
    std::cout << std::fixed << std::setprecision(3);
    std::cout << "diameter_px        truth  detected  precision  recall  f1     center_err_px\n";
    const auto line = [](const CraterMatchStats& b) {
      std::ostringstream range;
      range << std::setprecision(0) << std::fixed << b.min_diameter << "-"
            << (std::isfinite(b.max_diameter) ? std::to_string(static_cast<int>(b.max_diameter))
                                              : std::string("inf"));
      std::cout << std::left << std::setw(18) << range.str() << std::right << std::setw(6)
                << b.truth << std::setw(10) << b.detected << std::setw(11) << b.precision
                << std::setw(8) << b.recall << std::setw(7) << b.f1 << std::setw(10)
                << b.median_center_error << "\n";
    };
    for (const auto& b : s.bins) line(b);
    line(s.all);
    (void)global;
  });
  cmd->callback([cmd, args, &global] {
    if (!cmd->get_subcommands().empty()) return;  // `craters score` ran
    if (args->input.empty()) throw Error("craters: missing INPUT raster (or use 'craters score')");
    if (args->out_dir.empty()) throw Error("craters: --out DIR is required");
    if (args->detector.shading_template.enabled && !args->dtm && args->method == "learned")
      throw Error(
          "craters: --shading-templates belongs to --method edges (the learned detector finds "
          "degraded bowls without it)");
    if (args->detector.shading_template.enabled && args->dtm)
      throw Error(
          "craters: --shading-templates needs an image, not a DTM (the bowl's shading depends on "
          "where the sun is)");
    RunDetect(*args, global);
  });
}

}  // namespace areomap::cli
