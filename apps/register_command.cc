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
#include "areomap/registration/orbital_match.h"
#include "areomap/registration/orbital_report.h"
#include "areomap/registration/ortho_registration.h"
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
  std::string orbital_dtm;
  OrthoRegistrationOptions options;
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

void Run(RegisterArgs& args, const GlobalOptions& global) {
  RequireOption(args.prior_lat_deg.has_value() == args.prior_lon_deg.has_value(),
                "--prior-lat/--prior-lon", "both or neither");
  if (args.prior_lat_deg) {
    args.options.prior_position =
        Geographic{RadFromDeg(*args.prior_lat_deg), RadFromDeg(*args.prior_lon_deg),
                   args.options.prior_height_m};
  }
  args.options.Check();
  std::vector<std::filesystem::path> inputs = {args.ortho, args.orbital_dtm};
  inputs.insert(inputs.end(), args.orbitals.begin(), args.orbitals.end());
  OutputFolder out(args.out_dir, OutputPolicy(global, "register", kOutputs, inputs));

  const ProgressCallback progress = MakeProgressBar(global, "register");
  const OrthoRegistration registration = RegisterOrtho(
      args.ortho, {args.orbitals.begin(), args.orbitals.end()},
      args.orbital_dtm.empty() ? std::nullopt
                               : std::optional<std::filesystem::path>(args.orbital_dtm),
      args.options,
      [&](double fraction, std::string_view stage) { return progress(0.9 * fraction, stage); });
  const MultiOrbitalMatch& result = registration.result;

  nlohmann::json summary = OrthoRegistrationJson(registration);
  summary["command"] = "register";
  summary["ortho"] = args.ortho;
  for (size_t k = 0; k < result.matches.size(); ++k) {
    const OrbitalMatch& m = result.matches[k];
    if (!m.surface.empty()) {
      const std::string name = "cc_surface_" + std::to_string(k) + ".png";
      WriteImage(out / name, CorrelationSurfaceImage(m));
      summary["matches"][k]["cc_surface_png"] = name;
    }
  }
  if (result.best >= 0) {
    const EdgeVerification& edges = *registration.edges;
    WriteImage(out / "wvv_histograms.png", WorldViewVectorHistogramImage(edges));
    summary["edges"]["histograms_png"] = "wvv_histograms.png";
    const std::vector<OrbitalControlPoint>& points = registration.control_points;
    WriteFileAtomically(out / "control_points.json", ControlPointsJson(points).dump(2) + "\n");
    WriteFileAtomically(out / "control_points.csv", ControlPointsCsv(points));
    WriteRegisteredOrtho(out / "registered_ortho.tif", registration.ortho,
                         *registration.corrected_geotransform);
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
      ->add_option("--prior-height", args->options.prior_height_m,
                   "Height above the ellipsoid used without a DTM [m]")
      ->check(FiniteNumber())
      ->capture_default_str();
  prior
      ->add_option("--prior-sigma-m", args->options.prior_sigma_m,
                   "Horizontal 1-sigma of the prior [m]; the search covers 3 sigma")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--orbital-dtm", args->orbital_dtm, "Orbital DTM for control point heights");
  cmd->add_option("--site", args->options.site,
                  "MER site index: control points also in its site frame (origin: the prior)")
      ->check(IntegerAtLeast(0));
  auto* matching = cmd->add_option_group("Matching");
  matching
      ->add_option("--range-m", args->options.match.template_options.reliable_range_m,
                   "Reliable range kept around the rover [m] (0 = all)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  matching
      ->add_option("--max-rotation-deg", args->options.match.max_rotation_deg,
                   "Rotation (heading error) searched: +-this [deg]")
      ->check(NumberIn(0.0, 45.0))
      ->capture_default_str();
  matching
      ->add_option("--max-scale-change", args->options.match.max_scale_change,
                   "Scale searched: 1 +- this")
      ->check(NumberIn(0.0, 0.5, Bound::kClosed, Bound::kOpen))
      ->capture_default_str();
  matching
      ->add_option("--max-false-match", args->options.match.max_false_match,
                   "Accept a match only if the probability that its peak is a chance alignment "
                   "is at most this (the false-accept rate)")
      ->check(NumberIn(0.0, 1.0, Bound::kOpen, Bound::kClosed))
      ->capture_default_str();
  matching->add_flag("--similarity", args->options.similarity,
                     "Edge refinement fits a similarity instead of a translation");
  cmd->callback([args, &global] { Run(*args, global); });
}

}  // namespace areomap::cli
