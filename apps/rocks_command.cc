// areomap rocks extract CLOUD.ply --out DIR: rock peaks, surface points and models
// (ch. 2.2.2, 2.3); areomap rocks match A.ply B.ply --prior N,E,D,HEADING --out DIR: cross-site tie
// points with fault detection (ch. 3.2, 4.2).
#include <array>
#include <cmath>
#include <iostream>
#include <numbers>
#include <sstream>

#include "areomap/landmarks/rock_output.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/pipeline/rock_pair.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct RocksArgs {
  std::string cloud;
  std::string cloud_b;
  std::string out_dir;
  std::string prior;  // "north,east,down,heading_deg": site b in site a.
  std::string image;  // extract: the cloud's left image, for rocks_image.png (optional).
  int image_pair = 0;
  double prior_sigma_m = 1.0;
  double prior_heading_sigma_deg = 2.0;
  RockExtractionOptions extraction;
  RockMatchingOptions matching;
};

// "n,e,d,heading" -> pose of site b in site a (heading: b's frame turned clockwise from a's).
RockMatchingPrior ParsePrior(const RocksArgs& a) {
  std::array<double, 4> v{};
  std::stringstream in(a.prior);
  std::string field;
  size_t count = 0;
  while (std::getline(in, field, ',')) {
    if (count >= v.size()) break;
    try {
      size_t used = 0;
      v[count] = std::stod(field, &used);
      if (used != field.size() || !std::isfinite(v[count])) throw std::invalid_argument(field);
    } catch (const std::exception&) {
      throw Error("--prior: '" + field +
                  "' is not a number (expected north,east,down,heading_deg)");
    }
    ++count;
  }
  if (count != 4 || in.rdbuf()->in_avail() > 0) {
    throw Error("--prior '" + a.prior +
                "': expected 4 numbers north,east,down,heading_deg (site b in site a)");
  }
  RockMatchingPrior prior;
  prior.a_from_b = Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(v[3] * std::numbers::pi / 180.0,
                                                                Eigen::Vector3d::UnitZ())),
                           Eigen::Vector3d(v[0], v[1], v[2]));
  prior.position_sigma_m = a.prior_sigma_m;
  prior.heading_sigma_deg = a.prior_heading_sigma_deg;
  prior.source = "command line";
  prior.Check();
  return prior;
}

SiteRocks ExtractFrom(const std::string& path, const RocksArgs& a, int fallback_site,
                      RockExtractionSummary* summary, const GlobalOptions& global,
                      PointCloud* keep = nullptr) {
  PointCloud cloud = ReadPointCloudPly(path);
  SiteRocks rocks;
  rocks.site = cloud.site >= 0 ? cloud.site : fallback_site;
  rocks.camera_center = cloud.camera_center;
  rocks.rocks = ExtractRocks(cloud, a.extraction, summary, MakeProgressBar(global, "rocks"));
  if (keep) *keep = std::move(cloud);
  return rocks;
}

void RunExtract(const RocksArgs& a, const GlobalOptions& global) {
  a.extraction.Check();
  OutputFolder out(a.out_dir,
                   OutputPolicy(global, "rocks extract",
                                {"rocks.csv", "rocks.json", "rocks.png", "rocks_image.png"},
                                {a.cloud, a.image}));
  const cv::Mat image = a.image.empty() ? cv::Mat() : ReadImage(a.image);  // Fails before work.
  RockExtractionSummary summary;
  PointCloud cloud;
  const SiteRocks rocks = ExtractFrom(a.cloud, a, 0, &summary, global, &cloud);
  // Drawn before anything is written: a wrong image or pair leaves no partial output.
  const cv::Mat overlay = image.empty()
                              ? cv::Mat()
                              : RenderRocksImage(image, cloud, rocks.rocks, a.image_pair, a.image);
  WriteRocksCsv(out / "rocks.csv", rocks.rocks);
  WriteRocksJson(out / "rocks.json", rocks.rocks);
  WriteRocksPlotPng(out / "rocks.png", cloud, rocks.rocks, a.extraction.max_peak_range_m);
  nlohmann::json files = {"rocks.csv", "rocks.json", "rocks.png"};
  if (!overlay.empty()) {
    WriteImage(out / "rocks_image.png", overlay);
    files.push_back("rocks_image.png");
  }
  WriteSummary(out.dir(), {{"command", "rocks extract"},
                           {"input", a.cloud},
                           {"site", rocks.site},
                           {"extraction", RockExtractionSummaryToJson(summary)},
                           {"files", files}});
  out.Commit();  // Also removes an earlier run's rocks_image.png when no --image this time.
  if (!global.quiet) {
    std::cout << summary.rocks << " rocks (" << summary.modeled << " modeled) from "
              << summary.points << " points; wrote " << a.out_dir << "\n";
  }
}

void RunMatch(const RocksArgs& a, const GlobalOptions& global) {
  a.extraction.Check();
  a.matching.Check();
  CheckModelsCoverHeightRule(a.extraction, a.matching);
  const RockMatchingPrior prior = ParsePrior(a);
  OutputFolder out(a.out_dir, OutputPolicy(global, "rocks match",
                                           {"rocks_a.csv", "rocks_b.csv", "matches.csv",
                                            "tie_points.json", "faults.json", "faults.txt"},
                                           {a.cloud, a.cloud_b}));
  RockExtractionSummary summary_a, summary_b;
  SiteRocks rocks_a = ExtractFrom(a.cloud, a, 0, &summary_a, global);
  SiteRocks rocks_b = ExtractFrom(a.cloud_b, a, 1, &summary_b, global);
  if (rocks_a.site == rocks_b.site) rocks_b.site = rocks_a.site + 1;  // Tie-point ids differ.
  const SitePairMatch match = MatchRockPair(rocks_a, rocks_b, prior, a.matching, out.dir());
  WriteRocksCsv(out / "rocks_a.csv", rocks_a.rocks);
  WriteRocksCsv(out / "rocks_b.csv", rocks_b.rocks);
  nlohmann::json summary = {
      {"command", "rocks match"},
      {"input_a", a.cloud},
      {"input_b", a.cloud_b},
      {"site_a", rocks_a.site},
      {"site_b", rocks_b.site},
      {"prior",
       {{"north_m", prior.a_from_b.translation.x()},
        {"east_m", prior.a_from_b.translation.y()},
        {"down_m", prior.a_from_b.translation.z()},
        {"position_sigma_m", prior.position_sigma_m},
        {"heading_sigma_deg", prior.heading_sigma_deg}}},
      {"extraction_a", RockExtractionSummaryToJson(summary_a)},
      {"extraction_b", RockExtractionSummaryToJson(summary_b)},
      {"eligible_a", match.eligible_a},
      {"eligible_b", match.eligible_b},
      {"significant", match.significant},
      // The global pattern: b's rocks, put in a by the prior, lie off by this translation and
      // turn (the prior's error as the rocks measure it).
      {"pattern",
       {{"translation_m",
         {match.global_translation.x(), match.global_translation.y(),
          match.global_translation.z()}},
        {"turn_deg", match.global_turn_deg}}},
      {"rock_matches", match.matches.size()},
      {"tie_points", match.tie_points.size()},
      {"outcome", ToString(match.report.outcome)},
      {"relative_error_percent",
       match.error ? nlohmann::json(match.error->relative_error_percent) : nlohmann::json()},
      {"files",
       {"rocks_a.csv", "rocks_b.csv", "matches.csv", "tie_points.json", "faults.json",
        "faults.txt"}}};
  WriteSummary(out.dir(), summary);
  out.Commit();
  if (!global.quiet) {
    std::cout << "sites " << rocks_a.site << "-" << rocks_b.site << ": "
              << ToString(match.report.outcome) << ", " << match.matches.size() << " rock matches, "
              << match.tie_points.size() << " tie points";
    if (match.error) std::cout << ", RE " << match.error->relative_error_percent << " %";
    std::cout << "; wrote " << a.out_dir << "\n";
  }
}

void AddExtractionOptions(CLI::App* cmd, RockExtractionOptions& o) {
  cmd->add_option("--window", o.peak_window_m, "Peak window edge [m]")
      ->check(NumberIn(0.05, 10.0, Bound::kOpen, Bound::kOpen))
      ->capture_default_str();
  cmd->add_option("--min-relief", o.min_peak_relief_m, "Elevation range within the window [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--max-range", o.max_peak_range_m, "Peaks beyond this from the camera [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--min-height", o.min_height_m, "Lowest rock kept (peak to plane) [m]")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  cmd->add_option("--model-min-height", o.model_min_height_m, "Lowest rock modeled [m]")
      ->check(NonNegativeNumber())
      ->capture_default_str();
}

}  // namespace

// What `areomap rocks --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kRocksDetails =
    "Rock landmarks from a stereo cloud (ch. 2.2.2, 2.3): peaks, background plane, height, "
    "surface\n"
    "points and the best of four models, as `rocks.csv`, `rocks.json` and a top-view plot\n"
    "`rocks.png`; `--image LEFT.png` also paints the rocks over the cloud's left image\n"
    "(`rocks_image.png`). `match`: cross-site tie points (ch. 3.2) with the Table 4.5 fault "
    "report;\n"
    "`--prior-sigma`/`--prior-heading-sigma` bound the search; `--tie-variance-factor` scales the\n"
    "tie covariances (fit, RE, output); `--min-peak-to-plane` sets the height rule; two rocks are\n"
    "compared by their measured heights, with `--compare-models` by their models (eq. 3.28) where\n"
    "both rest on `--min-shape-points` (40) surface points or more; `--low-pair-height` (0.16 m)\n"
    "the height under which a pair of rocks is matched only between precise peaks, unless the\n"
    "global pattern vouches for it (its translation within `--pattern-vouch`, 0.2 m, of the\n"
    "pattern's with `--pattern-vouch-votes`, 3, votes; such a pair is matched whatever its cost,\n"
    "and a neighbour that would put the translation off the pattern does not make it ambiguous; "
    "the\n"
    "pattern's translation and turn, fitted to the rocks, are in `summary.json`'s `pattern`).\n"
    "Writes `matches.csv`, `tie_points.json`, `faults.json/txt`. Findings on the demo and K10 "
    "data:\n"
    "docs/rocks.md.";

void AddRocksCommand(CLI::App& app, const GlobalOptions& global) {
  auto* cmd = app.add_subcommand("rocks", "Rock landmarks from stereo point clouds (PLY)");
  cmd->footer(kRocksDetails);
  cmd->require_subcommand(1);

  auto extract_args = std::make_shared<RocksArgs>();
  auto* extract = cmd->add_subcommand(
      "extract", "Rock peaks, heights, surface points and models of one site's cloud");
  extract->add_option("cloud", extract_args->cloud, "Point cloud (areomap PLY)")->required();
  extract->add_option("--out", extract_args->out_dir, "Output folder")->required();
  extract
      ->add_option("--image", extract_args->image,
                   "The cloud's left image: also write rocks_image.png (rocks over it)")
      ->check(CLI::ExistingFile);
  extract
      ->add_option("--pair", extract_args->image_pair,
                   "Which stereo pair of the site --image is (the cloud's image_id)")
      ->check(IntegerIn(0, 65535))  // image_id is 16 bits
      ->capture_default_str();
  AddExtractionOptions(extract, extract_args->extraction);
  extract->callback([extract_args, &global] { RunExtract(*extract_args, global); });

  auto match_args = std::make_shared<RocksArgs>();
  auto* match = cmd->add_subcommand(
      "match", "Cross-site tie points between two sites' clouds, with fault detection");
  match->add_option("cloud_a", match_args->cloud, "Site a's point cloud (areomap PLY)")->required();
  match->add_option("cloud_b", match_args->cloud_b, "Site b's point cloud (areomap PLY)")
      ->required();
  match
      ->add_option("--prior", match_args->prior,
                   "Site b in site a: north,east,down [m],heading [deg clockwise]")
      ->required();
  match
      ->add_option("--prior-sigma", match_args->prior_sigma_m,
                   "1-sigma of the prior position, per axis [m] (a large one: position unknown, "
                   "--search-radius bounds the search)")
      ->check(PositiveNumber())
      ->capture_default_str();
  match
      ->add_option("--prior-heading-sigma", match_args->prior_heading_sigma_deg,
                   "1-sigma of the prior heading [deg]")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  match
      ->add_option("--search-radius", match_args->matching.search_radius_m,
                   "Largest search radius around a rock [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  match
      ->add_option("--tie-variance-factor", match_args->matching.tie_variance_factor,
                   "Variance factor of the tie points' eq. 4.3 covariances (a run's pooled "
                   "sigma0^2, summary.json rock_tie_variance) for the fit, RE and the output")
      ->check(PositiveNumber())
      ->capture_default_str();
  AddRockPairOptions(match, &match_args->matching);
  auto* rule = match->add_option(
      "--min-peak-to-plane", match_args->matching.fault_detection.min_peak_to_plane_m,
      "Table 4.5's height rule: lower rocks are not tie points [m] (measured heights "
      "run 2-6 cm under the true ones, docs/rocks.md; --model-min-height follows "
      "it unless given)");
  rule->check(NonNegativeNumber())->capture_default_str();
  match->add_option("--out", match_args->out_dir, "Output folder")->required();
  AddExtractionOptions(match, match_args->extraction);
  match->callback([match_args, match, rule, &global] {
    if (rule->count() > 0 && match->get_option("--model-min-height")->count() == 0) {
      match_args->extraction.model_min_height_m =
          match_args->matching.fault_detection.min_peak_to_plane_m;
    }
    RunMatch(*match_args, global);
  });
}

}  // namespace areomap::cli
