// areomap register ORTHO ORBITAL... --out DIR: put a rover orthophoto where it belongs on
// orbital images (masked NCC, coarse to fine), verify by edges, write control points.
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <vector>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/raster.h"
#include "areomap/registration/edge_histogram.h"
#include "areomap/registration/edge_verify.h"
#include "areomap/registration/orbital_grid.h"
#include "areomap/registration/orbital_match.h"
#include "areomap/registration/orbital_report.h"
#include "commands.h"

namespace areomap::cli {
namespace {

// The files `register` writes: one cc_surface_K.png per orbital image, and the others only when an
// orbital image matched.
const std::vector<std::string> kOutputs = {"cc_surface_*.png", "wvv_histograms.png",
                                           "control_points.json", "control_points.csv",
                                           "registered_ortho.tif"};

struct RegisterArgs {
  std::string ortho;
  std::vector<std::string> orbitals;
  std::string out_dir;
  std::optional<double> prior_lat_deg;
  std::optional<double> prior_lon_deg;
  double prior_height_m = 0.0;
  double prior_sigma_m = 10.0;
  std::string orbital_dtm;
  std::optional<int> site;
  bool similarity = false;
  OrbitalMatchOptions match;
  ControlPointOptions control;
};

constexpr double kNoData = -3.4028227e+38;

void WriteRegisteredOrtho(const std::filesystem::path& path, const OrthoImage& ortho,
                          const GeoTransform& corrected) {
  GeoRaster raster;
  cv::Mat values = ortho.image.clone();
  values.setTo(kNoData, ~ortho.ValidMask());
  raster.bands = {values};
  raster.band_names = {"orthophoto"};
  raster.geotransform = corrected;
  raster.crs_wkt = ortho.crs_wkt;
  raster.nodata = kNoData;
  WriteGeoTiff(path, raster);
}

// The centre of the whole orthophoto file in pixels of `ortho` (ReadOrthoImage keeps only the
// window of its valid pixels): the default prior stays the file's centre, read from its metadata.
Eigen::Vector2d FileCentreInOrtho(const std::string& path, const OrthoImage& ortho) {
  const RasterInfo info = RasterDataset::Open(path).info();
  const Eigen::Vector2d centre =
      info.geotransform.value().PixelToMap(info.width / 2.0, info.height / 2.0);
  return ortho.geotransform.MapToPixel(centre.x(), centre.y());
}

void Run(RegisterArgs& args, const GlobalOptions& global) {
  args.match.Check();
  args.control.Check();
  RequireOption(args.prior_lat_deg.has_value() == args.prior_lon_deg.has_value(),
                "--prior-lat/--prior-lon", "both or neither");
  std::vector<std::filesystem::path> inputs = {args.ortho, args.orbital_dtm};
  inputs.insert(inputs.end(), args.orbitals.begin(), args.orbitals.end());
  OutputFolder out(args.out_dir, OutputPolicy(global, "register", kOutputs, inputs));
  OrthoImage ortho = ReadOrthoImage(args.ortho);
  const PixelGrid ortho_grid(ortho.geotransform, ortho.crs_wkt, ortho.source);
  OrbitalPrior prior;
  prior.sigma_m = args.prior_sigma_m;
  if (args.prior_lat_deg) {
    prior.position = {RadFromDeg(*args.prior_lat_deg), RadFromDeg(*args.prior_lon_deg),
                      args.prior_height_m};
  } else {
    // Without telemetry: the orthophoto's centre as its georeference has it, the point of that
    // pixel's radial line at the given height.
    const auto centre = ortho_grid.PixelToGeographic(FileCentreInOrtho(args.ortho, ortho));
    if (!centre) throw Error(args.ortho + ": its centre lies outside its CRS's domain");
    prior.position = GeographicFromMbf(
        prior.body, MbfOnRadialLine(prior.body, centre->lat, centre->lon, args.prior_height_m));
  }
  if (args.site) {
    ortho.site = *args.site;
    ortho.site_origin = prior.position;
  }
  std::vector<OrbitalImage> orbitals;
  for (const std::string& path : args.orbitals) orbitals.push_back(OrbitalImage::Open(path));
  std::optional<OrbitalImage> dtm;
  if (!args.orbital_dtm.empty()) dtm = OrbitalImage::Open(args.orbital_dtm);

  const ProgressCallback progress = MakeProgressBar(global, "register");
  const MultiOrbitalMatch result = MatchOrthoToOrbitals(
      ortho, orbitals, prior, args.match,
      [&](double fraction, std::string_view stage) { return progress(0.9 * fraction, stage); });
  bool any_overlap = false;
  for (const OrbitalMatch& m : result.matches) any_overlap = any_overlap || m.overlaps;
  if (!any_overlap) {
    char where[160];  // %.0f: a radius beyond int (--prior-sigma-m 1e9) printed as it is
    std::snprintf(where, sizeof(where), "%.0f m around latitude %.6f, longitude %.6f deg",
                  args.match.search_sigmas * prior.sigma_m, DegFromRad(prior.position.lat),
                  DegFromRad(prior.position.lon));
    throw Error(std::string("no orbital image overlaps the search window: ") + where);
  }

  nlohmann::json summary = {{"command", "register"},
                            {"ortho", args.ortho},
                            {"prior",
                             {{"lat_deg", DegFromRad(prior.position.lat)},
                              {"lon_deg", DegFromRad(prior.position.lon)},
                              {"sigma_m", prior.sigma_m}}},
                            {"matches", nlohmann::json::array()}};
  for (size_t k = 0; k < result.matches.size(); ++k) {
    const OrbitalMatch& m = result.matches[k];
    nlohmann::json j = MatchJson(m);
    if (!m.surface.empty()) {
      const std::string name = "cc_surface_" + std::to_string(k) + ".png";
      WriteImage(out / name, CorrelationSurfaceImage(m));
      j["cc_surface_png"] = name;
    }
    summary["matches"].push_back(j);
  }
  summary["matched"] = result.best >= 0;
  if (result.best >= 0) {
    const OrbitalMatch& best = result.matches[result.best];
    const OrbitalImage& orbital = orbitals[result.best];
    summary["best"] = result.best;
    EdgeVerificationOptions edge_options;
    edge_options.fit_similarity = args.similarity;
    const EdgeVerification edges = VerifyMatchWithEdges(best, edge_options);
    WriteImage(out / "wvv_histograms.png", WorldViewVectorHistogramImage(edges));
    summary["edges"] = {
        {"ortho_edges", edges.ortho_edges},
        {"orbital_edges", edges.orbital_edges},
        {"pairs_per_group_0_1_2_3_px", edges.pairs_per_group},
        {"ortho_rate", edges.ortho_rate},
        {"orbital_rate", edges.orbital_rate},
        {"world_view_vector_matches", edges.pattern_pairs},
        {"fitted", edges.fitted},
        {"residual_shift_px", {edges.shift_px.x(), edges.shift_px.y()}},
        {"residual_rotation_deg", DegFromRad(edges.rotation_rad)},
        {"residual_scale", edges.scale},
        {"inliers", edges.inliers},
        {"rms_px", std::isfinite(edges.rms_px) ? nlohmann::json(edges.rms_px) : nlohmann::json()},
        {"consistent", edges.consistent},
        {"histograms_png", "wvv_histograms.png"}};
    const std::vector<OrbitalControlPoint> points =
        MakeControlPoints(best, ortho, orbital, prior, dtm, args.control);
    WriteFileAtomically(out / "control_points.json", ControlPointsJson(points).dump(2) + "\n");
    WriteFileAtomically(out / "control_points.csv", ControlPointsCsv(points));
    WriteRegisteredOrtho(out / "registered_ortho.tif", ortho,
                         CorrectedGeoTransform(best, ortho, orbital));
    summary["control_points"] = points.size();
    summary["control_points_json"] = "control_points.json";
    summary["control_points_csv"] = "control_points.csv";
    summary["registered_ortho"] = "registered_ortho.tif";
    if (!global.quiet) {
      std::cout << "edges: " << edges.BriefReport() << "\n";
    }
  }
  WriteSummary(out.dir(), summary);
  // Without a match no control points: Commit() removes an earlier match's.
  out.Commit();
  progress(1.0, "done");
  if (!global.quiet) {
    for (const OrbitalMatch& m : result.matches) std::cout << m.BriefReport() << "\n";
    if (result.best >= 0) {
      std::cout << "best: " << result.matches[result.best].orbital << "\n";
    } else {
      std::cout << "no match: no orbital image gives a confident match\n";
    }
  }
}

}  // namespace

// What `areomap register --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kRegisterDetails =
    "Puts a rover orthophoto (any Mars GeoTIFF; nodata or band 2 = validity mask) where it "
    "belongs\n"
    "on one or more orbital images: resampled to the orbital GSD (Gaussian low-pass, 80 m "
    "reliable\n"
    "range, `--range-m`), masked NCC in the Fourier domain coarse to fine inside the prior's "
    "window\n"
    "(`--prior-lat/--prior-lon/--prior-sigma-m`, 3 sigma), optional rotation/scale search\n"
    "(`--max-rotation-deg`, `--max-scale-change`; the best grid value refined at full "
    "resolution),\n"
    "subpixel peak; \"no match\" when the probability that the peak is a chance alignment (the "
    "peak\n"
    "against the correlation surface at wrong shifts, random field theory:\n"
    "`registration/include/areomap/registration/peak_significance.h`) exceeds `--max-false-match`\n"
    "(default 1e-3), reported per match as `false_match_probability` in `summary.json` and the\n"
    "control points. Writes the rover's correction (east/north m, 1 sigma; with a rotation, the\n"
    "template's shift plus its turn about the rover, and the rotation's error times the rover's\n"
    "lever in the sigma; `rotation_sigma_deg`) and corrected position, CC surface PNGs, "
    "Canny-edge\n"
    "verification with Table 3.7 statistics and Fig. 3.15 world-view-vector histograms, the\n"
    "registered orthophoto (only the window of its valid pixels is read and written; one without\n"
    "valid pixels is refused), control points (ortho px, orbital px, lat/lon/h from\n"
    "`--orbital-dtm`, MBF and `--site` frame, covariance) as JSON/CSV, and `summary.json`.";

void AddRegisterCommand(CLI::App& app, const GlobalOptions& global) {
  auto args = std::make_shared<RegisterArgs>();
  auto* cmd = app.add_subcommand(
      "register", "Register a rover orthophoto onto orbital images (masked NCC, edge check)");
  cmd->footer(kRegisterDetails);
  cmd->add_option("ortho", args->ortho, "Rover orthophoto GeoTIFF (nodata or band 2 = mask)")
      ->required();
  cmd->add_option("orbital", args->orbitals, "Orbital images (any Mars GDAL raster)")->required();
  cmd->add_option("--out", args->out_dir, "Output folder (created if needed)")->required();
  auto* prior = cmd->add_option_group("Prior (telemetry)");
  prior
      ->add_option("--prior-lat", args->prior_lat_deg,
                   "Rover planetocentric latitude [deg] (default: the ortho's centre)")
      ->check(Latitude());
  prior->add_option("--prior-lon", args->prior_lon_deg, "Rover east longitude [deg]")
      ->check(Longitude());
  prior
      ->add_option("--prior-height", args->prior_height_m,
                   "Height above the ellipsoid used without a DTM [m]")
      ->check(FiniteNumber())
      ->capture_default_str();
  prior
      ->add_option("--prior-sigma-m", args->prior_sigma_m,
                   "Horizontal 1-sigma of the prior [m]; the search covers 3 sigma")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--orbital-dtm", args->orbital_dtm, "Orbital DTM for control point heights");
  cmd->add_option("--site", args->site,
                  "MER site index: control points also in its site frame (origin: the prior)")
      ->check(IntegerAtLeast(0));
  auto* matching = cmd->add_option_group("Matching");
  matching
      ->add_option("--range-m", args->match.template_options.reliable_range_m,
                   "Reliable range kept around the rover [m] (0 = all)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  matching
      ->add_option("--max-rotation-deg", args->match.max_rotation_deg,
                   "Rotation (heading error) searched: +-this [deg]")
      ->check(NumberIn(0.0, 45.0))
      ->capture_default_str();
  matching
      ->add_option("--max-scale-change", args->match.max_scale_change, "Scale searched: 1 +- this")
      ->check(NumberIn(0.0, 0.5, Bound::kClosed, Bound::kOpen))
      ->capture_default_str();
  matching
      ->add_option("--max-false-match", args->match.max_false_match,
                   "Accept a match only if the probability that its peak is a chance alignment "
                   "is at most this (the false-accept rate)")
      ->check(NumberIn(0.0, 1.0, Bound::kOpen, Bound::kClosed))
      ->capture_default_str();
  matching->add_flag("--similarity", args->similarity,
                     "Edge refinement fits a similarity instead of a translation");
  cmd->callback([args, &global] { Run(*args, global); });
}

}  // namespace areomap::cli
