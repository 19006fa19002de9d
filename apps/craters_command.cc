// areomap craters IMAGE|DTM --out DIR: crater rims, ellipses and models (IMAGE... or --list FILE:
// a catalogue, craters_catalogue.cc); areomap craters score.
#include <cmath>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "areomap/crater/crater_image.h"
#include "areomap/crater/crater_output.h"
#include "areomap/crater/crater_score.h"
#include "areomap/map/error.h"
#include "commands.h"
#include "craters_args.h"

namespace areomap::cli {

CraterImageOptions ImageOptions(const CratersArgs& args) {
  CraterImageOptions options = args.image;
  options.diameters_in_metres = args.units == "m";
  options.detector.method = CraterMethodFromString(args.method);
  return options;
}

namespace {

// One raster: today's `areomap craters IMAGE --out DIR` (crater_image.h).
void RunDetect(const CratersArgs& a, const GlobalOptions& global) {
  const CraterImageOptions options = ImageOptions(a);
  const CraterImageJob job =
      PrepareCraterImage(a.inputs.front(), options, MakeProgressBar(global, "sun azimuth"));
  for (const std::string& w : job.warnings) std::cerr << "warning: " << w << "\n";
  if (!global.quiet) {
    for (const std::string& note : job.notes) std::cout << note << "\n";
  }
  OutputFolder folder(a.out_dir,
                      OutputPolicy(global, "craters",
                                   {"craters.csv", "craters.json", "craters.gpkg", "overlay.png"},
                                   {a.inputs.front()}));
  const CraterImageResult result =
      DetectCraterImage(job, folder.dir(), MakeProgressBar(global, "craters"));
  WriteSummary(folder.dir(), CraterImageSummaryJson(job, result));
  folder.Commit();  // Also removes an earlier run's craters.gpkg when this input has no CRS.
  for (const std::string& w : result.warnings) std::cerr << "warning: " << w << "\n";
  if (!global.quiet) {
    std::cout << "found " << result.craters << " craters (" << result.partial << " partial) in "
              << a.inputs.front() << "; wrote " << a.out_dir << "\n";
  }
}

}  // namespace

// What `areomap craters --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kCratersDetails =
    "Crater rims as ellipses with 1σ. Images, default `--method combined`: both detectors below,\n"
    "every edge rim that the network also sees (`--edge-support`) plus each crater only the\n"
    "network found (`edge_detected` 0), F1 0.77 on held-out CTX and 0.60 on HRSC against 0.32\n"
    "and 0.44 for the edges alone. `--method edges`\n"
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
    "when georeferenced), `overlay.png`, `summary.json`. Two or more images, or `--list FILE`: a\n"
    "catalogue; each image (georeferenced, projected Mars CRS) into `images/<NNN>_<stem>/` as\n"
    "above plus `image.json`, one after the other, then one `craters.gpkg` and `craters.csv` in\n"
    "the first image's CRS (or `--crs`) with each crater once where images overlap (the better-\n"
    "fitted rim kept) and `images.csv`, a row per image; an image that fails is a row, the others\n"
    "go on, the exit status is non-zero (docs/crater-catalogue.md). `craters score DETECTIONS.csv\n"
    "TRUTH.csv [--image IMAGE --out DIR]`: precision, recall, F1 by diameter bin. Speed and\n"
    "accuracy: docs/benchmarks.md (Craters).";

void AddCraterDetectionOptions(CLI::App* cmd, CratersArgs* args) {
  cmd->add_option("--crs", args->crs,
                  "Catalogue: CRS of the merged catalogue, a projected Mars CRS in metres "
                  "(IAU_2015:49910, WKT, PROJ); default: the first image's");
  cmd->add_flag("--dtm", args->image.dtm, "The input holds heights: rims from curvature crests");
  cmd->add_option("--method", args->method,
                  "Image detector: combined (both below, the network's finds added to the edge "
                  "rims), edges (rim edges to ellipses) or learned (trained network, rims "
                  "refitted as ellipses where they show edges; docs/crater-model.md). DTMs "
                  "always use edges")
      ->check(CLI::IsMember({"combined", "learned", "edges"}))
      ->capture_default_str();
  cmd->add_option("--model", args->image.detector.learned.model_path,
                  "learned, combined: ONNX crater model trained as the built-in one "
                  "(scripts/crater_model/train.py); default: built-in");
  cmd->add_option("--min-score", args->image.detector.learned.min_score,
                  "learned, combined: heat-map peak threshold in (0, 1)")
      ->check(NumberIn(0.0, 1.0, Bound::kOpen, Bound::kOpen))
      ->capture_default_str();
  cmd->add_option("--edge-support", args->image.detector.learned.edge_support_score,
                  "combined: keep an edge rim only where the network's heat map peaks at this "
                  "score or more on the same crater (0: keep every rim; over --min-score acts as "
                  "--min-score)")
      ->check(NumberIn(0.0, 1.0, Bound::kClosed, Bound::kOpen))
      ->capture_default_str();
  cmd->add_flag("--no-rim-fit{false}", args->image.detector.learned.refine_rims,
                "learned, combined: keep the network's circles, do not refit rims as ellipses");
  cmd->add_option("--units", args->units, "Unit of the diameter limits: px or m")
      ->check(CLI::IsMember({"px", "m"}))
      ->capture_default_str();
  // At least 4 px, checked in px once --units and the raster's pixel size are known.
  cmd->add_option("--min-diameter", args->image.min_diameter,
                  "Smallest rim diameter (at least 4 px); the network's circles without a rim "
                  "fit meet it and --max-diameter within 2 sigma (docs/crater-model.md)")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--max-diameter", args->image.max_diameter, "Largest rim diameter (0: no limit)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  cmd->add_option("--sun-azimuth", args->image.sun_azimuth_deg,
                  "Sun azimuth [deg clockwise from image up]: enables the shading checks")
      ->check(FiniteNumber());
  cmd->add_flag("!--no-sun-estimate", args->image.estimate_sun,
                "Without --sun-azimuth, do not estimate it from the shading of the image's craters "
                "(the shading checks stay off)");
  cmd->add_option("--tile-size", args->image.detector.tile_size, "Tile core edge [px]")
      ->check(IntegerAtLeast(256))
      ->capture_default_str();
  cmd->add_option("--tile-overlap", args->image.detector.tile_overlap,
                  "Tile margin [px] (at most --tile-size)")
      ->check(IntegerAtLeast(32))
      ->capture_default_str();
  cmd->add_option("--min-shading-contrast", args->image.detector.min_shading_contrast,
                  "Image with sun: wall contrast threshold")
      ->check(FiniteNumber())
      ->capture_default_str();
  cmd->add_option("--min-coverage", args->image.detector.min_coverage,
                  "Fraction of rim sectors that must hold edges")
      ->check(NumberIn(0.0, 1.0))
      ->capture_default_str();
  cmd->add_option("--max-axis-ratio", args->image.detector.max_axis_ratio, "Largest a / b accepted")
      ->check(NumberAtLeast(1.0))
      ->capture_default_str();
  cmd->add_option("--min-edge-contrast", args->image.detector.min_edge_contrast,
                  "Rim edge strength / high Canny threshold")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  cmd->add_flag("--no-upsample{false}", args->image.detector.upsample_small_craters,
                "Skip the 2x upsampled level for craters under 16 px across (faster; finds fewer "
                "of them)");
  cmd->add_flag("--shading-templates", args->image.detector.shading_template.enabled,
                "Also seek small degraded bowls by their shading (needs a sun azimuth, given or "
                "estimated; ~1.35x time)");
}

CratersArgs ParseCratersArguments(const std::vector<std::string>& arguments) {
  return ParsePlanArguments(arguments, &AddCraterDetectionOptions, "craters");
}

namespace {

// `areomap craters score DETECTIONS TRUTH [--out DIR [--image IMAGE]]`.
struct CraterScoreArgs {
  std::string detections, truth;
  std::string out;            // Also write summary.json (and the overlay) here.
  std::string image;          // With --out: draw score_overlay.png on this image.
  double min_diameter = 8.0;  // Smallest diameter scored [px] (0: all).
};

void PrintCraterScoreLine(const CraterMatchStats& b) {
  std::ostringstream range;
  range << std::setprecision(0) << std::fixed << b.min_diameter << "-"
        << (std::isfinite(b.max_diameter) ? std::to_string(static_cast<int>(b.max_diameter))
                                          : std::string("inf"));
  std::cout << std::left << std::setw(18) << range.str() << std::right << std::setw(6) << b.truth
            << std::setw(10) << b.detected << std::setw(11) << b.precision << std::setw(8)
            << b.recall << std::setw(7) << b.f1 << std::setw(10) << b.median_center_error << "\n";
}

void PrintCraterScoreTable(const CraterScore& s) {
  std::cout << std::fixed << std::setprecision(3);
  std::cout << "diameter_px        truth  detected  precision  recall  f1     center_err_px\n";
  for (const auto& b : s.bins) PrintCraterScoreLine(b);
  PrintCraterScoreLine(s.all);
}

nlohmann::json CraterScoreSummaryJson(const CraterScoreArgs& a, const CraterScore& s) {
  nlohmann::json summary = {
      {"command", "craters score"},
      {"detections", a.detections},
      {"truth", a.truth},
      {"rule", "centre distance < 0.5 x truth radius and detected/true diameter in [0.7, 1.3]"},
      {"all", CraterMatchStatsJson(s.all)},
      {"bins", nlohmann::json::array()}};
  for (const auto& b : s.bins) summary["bins"].push_back(CraterMatchStatsJson(b));
  return summary;
}

void RunCraterScore(const CraterScoreArgs& a, const GlobalOptions& global) {
  const std::vector<CraterCircle> detections = ReadCraterCsv(a.detections);
  const std::vector<CraterCircle> truth = ReadCraterCsv(a.truth);
  const double lo = a.min_diameter;
  const double inf = std::numeric_limits<double>::infinity();
  const CraterScore s = ScoreCraters(truth, detections, {lo, 2 * lo, 4 * lo, 8 * lo, inf});
  nlohmann::json summary = CraterScoreSummaryJson(a, s);
  if (!a.image.empty() && a.out.empty()) {
    throw Error("craters score: --image needs --out DIR for the overlay");
  }
  if (!a.out.empty()) {
    OutputFolder folder(a.out, OutputPolicy(global, "craters score", {"score_overlay.png"},
                                            {a.detections, a.truth, a.image}));
    if (!a.image.empty()) {
      const RasterDataset image = RasterDataset::Open(a.image);
      WriteScoreOverlay(folder / "score_overlay.png", image.ReadWindowFloat(1, image.FullWindow()),
                        truth, detections, s, lo);
      summary["overlay"] = "score_overlay.png";
    }
    WriteSummary(folder.dir(), summary);
    folder.Commit();
  }
  PrintCraterScoreTable(s);
}

void AddCraterScoreCommand(CLI::App* cmd, const GlobalOptions& global) {
  auto a = std::make_shared<CraterScoreArgs>();
  auto* score = cmd->add_subcommand(
      "score",
      "Precision, recall, F1 of detections against truth (CSV with x_px, y_px, diameter_px). "
      "Match: centre distance < 0.5 x truth radius and diameter ratio within +-30 %");
  score->add_option("detections", a->detections, "Detections CSV")->required();
  score->add_option("truth", a->truth, "Truth CSV")->required();
  score->add_option("--min-diameter", a->min_diameter, "Smallest diameter scored [px] (0: all)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  score->add_option("--out", a->out, "Also write DIR/summary.json");
  score->add_option("--image", a->image,
                    "With --out: also write DIR/score_overlay.png on this image (truth green when "
                    "matched, red when missed; false alarms yellow)");
  score->callback([a, &global] { RunCraterScore(*a, global); });
}

// `areomap craters INPUT... --out DIR`: one raster (RunDetect) or a catalogue, planned or not.
// `detection_group` holds the detection options, recorded as given in a plan.
void RunCratersCommand(const CratersArgs& args, const CLI::App& detection_group,
                       const GlobalOptions& global) {
  if (args.inputs.empty() && args.list.empty()) {
    throw Error("craters: missing INPUT raster (or use 'craters score')");
  }
  if (args.out_dir.empty()) throw Error("craters: --out DIR is required");
  ImageOptions(args).Check();
  const bool planned = args.executor.plan_only || args.executor.executor != "local";
  if (args.inputs.size() > 1 || !args.list.empty()) {
    if (planned) {
      RunPlannedCraterCatalogue(args, ArgumentsGiven(detection_group), global);
    } else {
      RunCraterCatalogue(args, global);
    }
    return;
  }
  if (planned) {
    throw Error(
        "craters: --plan and --executor belong to a catalogue (two or more images, or "
        "--list)");
  }
  if (!args.crs.empty()) {
    throw Error("craters: --crs belongs to a catalogue (two or more images, or --list)");
  }
  RunDetect(args, global);
}

}  // namespace

void AddCratersCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<CratersArgs>();
  CLI::App* detection_group = nullptr;
  auto* cmd = app.add_subcommand(
      "craters", "Detect crater rims in an image or DTM: ellipses, uncertainties, models");
  cmd->footer(kCratersDetails);
  cmd->require_subcommand(0, 1);
  cmd->add_option("input", args->inputs,
                  "Image or DTM raster (GeoTIFF, PNG, ISIS3, PDS...); two or more: a catalogue "
                  "(georeferenced, projected Mars CRS) merged in DIR");
  cmd->add_option("--list", args->list,
                  "Catalogue: also the images listed in FILE, one path a line (blank lines and "
                  "# comments skipped)");
  cmd->add_option("--out", args->out_dir, "Output folder (created if needed)");
  detection_group = cmd->add_option_group("Detection options");
  AddCraterDetectionOptions(detection_group, args.get());
  AddExecutorOptions(cmd, &args->executor);
  AddCraterScoreCommand(cmd, global);
  cmd->callback([cmd, args, detection_group, &global] {
    if (!cmd->get_subcommands().empty()) return;  // `craters score` ran
    RunCratersCommand(*args, *detection_group, global);
  });
}

}  // namespace areomap::cli
