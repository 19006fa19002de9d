// areomap stereo LEFT RIGHT --out DIR: dense stereo of one pair into a point cloud (points.ply),
// a disparity quick-look (disparity.png) and summary.json; with --tie-points also the sparse
// Förstner + NCC tie points of ch. 2.2.2 (tie_points.csv).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include <opencv2/core.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/camera_models.h"
#include "areomap/map/dense_stereo.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/interest_points.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/map/raster.h"
#include "areomap/map/sparse_stereo.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct StereoCommandOptions {
  std::string left, right, out;
  std::string left_camera, right_camera;  // Default: the labels beside (or inside) the images.
  bool write_rectified = false;
  bool tie_points = false;
  DenseStereoOptions stereo;
};

// Förstner points of the rectified left image matched into the rectified right image along the
// common CAHV pair's epipolar lines with the Table 4.5 filters (sparse_stereo.h). Pixels are
// rectified pixels; points are in the cloud's frame.
std::vector<SparseTiePoint> MatchSparseTiePoints(const DenseStereoResult& result,
                                                 const DenseStereoOptions& stereo) {
  const cv::Mat& left = result.disparity.left8;  // Both functions take 8-bit images as they are.
  SparseStereoOptions options;
  options.min_range_m = stereo.min_range_m;
  options.max_range_m = stereo.max_range_m;
  return MatchInterestPoints(left, result.disparity.right8, result.rectification.left,
                             result.rectification.right, DetectForstnerPoints(left), options);
}

std::string TiePointsCsv(const std::vector<SparseTiePoint>& ties) {
  std::ostringstream csv;
  csv << "left_x_px,left_y_px,right_x_px,right_y_px,correlation,vertical_disparity_px,range_m,"
         "x_m,y_m,z_m,forstner_weight,forstner_roundness\n"
      << std::fixed << std::setprecision(6);  // micro-pixels and micrometres
  for (const SparseTiePoint& t : ties) {
    if (!t.match.ok) continue;
    const SparseStereoMatch& m = t.match;
    csv << t.left.pixel.x() << ',' << t.left.pixel.y() << ',' << m.right_pixel.x() << ','
        << m.right_pixel.y() << ',' << m.correlation << ',' << m.vertical_disparity_px << ','
        << m.range_m << ',' << m.point.x() << ',' << m.point.y() << ',' << m.point.z() << ','
        << t.left.weight << ',' << t.left.roundness << '\n';
  }
  return csv.str();
}

// PNG/TIFF through OpenImageIO; planetary products (MER .IMG) through GDAL.
cv::Mat ReadStereoImage(const std::filesystem::path& path) {
  const std::string extension = path.extension().string();
  if (extension == ".png" || extension == ".PNG" || extension == ".tif" || extension == ".TIF" ||
      extension == ".jpg") {
    return ReadImage(path);
  }
  const RasterDataset dataset = RasterDataset::Open(path);
  return dataset.ReadWindow(1, dataset.FullWindow());
}

}  // namespace

// What `areomap stereo --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kStereoDetails =
    "Dense stereo of one pair (labels beside the images, or `--left-camera`/`--right-camera`\n"
    "CAHVOR/CAHVORE/`.tsai` files): epipolar rectification, SGBM in both directions with "
    "left–right\n"
    "check, triangulation with the eq. 4.3 covariance, a line-of-sight check that drops points\n"
    "buried under the ground seen in front of them (the rover's own deck) or floating over the\n"
    "ground seen behind them (`--no-line-of-sight` keeps them; docs/stereo.md), into "
    "`points.ply`,\n"
    "`disparity.png`, `summary.json` (valid fraction of the overlap, vertical disparity\n"
    "before/after the orientation fit). `--tie-points` adds `tie_points.csv`: Förstner interest\n"
    "points matched by NCC with the Table 4.5 filters (ch. 2.2.2).";

namespace {

void AddStereoOptions(CLI::App* cmd, StereoCommandOptions& o) {
  cmd->add_option("left", o.left, "Left image (PNG with a label beside it, or MER .IMG)")
      ->required();
  cmd->add_option("right", o.right, "Right image")->required();
  cmd->add_option("--out", o.out, "Output folder")->required();
  cmd->add_option("--left-camera", o.left_camera,
                  "Left camera model (.json label, .tsai, or labelled product)");
  cmd->add_option("--right-camera", o.right_camera, "Right camera model");
  DenseStereoOptions& s = o.stereo;
  cmd->add_option("--max-range", s.max_range_m,
                  "Drop points beyond this range [m] (beyond --min-range)")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--min-range", s.min_range_m, "Nearest range searched [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--block-size", s.block_size, "SGBM window [px]")
      ->check(OddIntegerIn(3, 11))
      ->capture_default_str();
  cmd->add_option("--uniqueness", s.uniqueness_ratio, "SGBM uniqueness margin [%]")
      ->check(IntegerIn(0, 100))
      ->capture_default_str();
  cmd->add_option("--lr-max-diff", s.lr_max_diff_px, "Left-right consistency tolerance [px]")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  cmd->add_option("--max-disparity-step", s.max_disparity_step_px,
                  "Disparity jump marking an occlusion edge [px] (0: keep edges)")
      ->check(NonNegativeNumber())
      ->capture_default_str();
  cmd->add_option("--occlusion-margin", s.occlusion_margin_px,
                  "Pixels dropped on each side of an occlusion edge [px] (-1: block size / 2)")
      ->check(IntegerIn(-1, 64))
      ->capture_default_str();
  cmd->add_option("--parallax-sigma", s.parallax_sigma_px, "sigma_p of eq. 4.3 [px]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_flag("--rectified", o.write_rectified,
                "Also write the rectified 8-bit pair (left_rectified.png, right_rectified.png)");
  cmd->add_flag("!--no-line-of-sight", s.check_line_of_sight,
                "Keep the points buried under the ground seen in front of them (the rover's own "
                "deck) or floating over the ground seen behind them; by default dropped "
                "(the frame's +z must point down)");
  cmd->add_flag("!--no-align-rows", s.align_rows,
                "Do not estimate the residual vertical disparity from tracked features");
  cmd->add_flag("--tie-points", o.tie_points,
                "Also match Förstner interest points (NCC >= 0.85 and the other Table 4.5 "
                "filters) into tie_points.csv");
  cmd->add_option("--image-id", s.image_id, "Pair id written into every point")
      ->check(IntegerIn(0, 65535))  // 16 bits
      ->capture_default_str();
}

// What one stereo run computed, before anything is written.
struct StereoRun {
  CameraFile left, right;
  DenseStereoResult result;
  std::vector<SparseTiePoint> ties;  // Empty without --tie-points.
  size_t accepted_ties = 0;
  double seconds = 0;
};

StereoRun ComputeStereo(const StereoCommandOptions& o, const GlobalOptions& global,
                        std::chrono::steady_clock::time_point start) {
  CameraFile left =
      o.left_camera.empty() ? ReadCameraForImage(o.left) : ReadCameraFile(o.left_camera);
  CameraFile right =
      o.right_camera.empty() ? ReadCameraForImage(o.right) : ReadCameraFile(o.right_camera);
  const cv::Mat left_image = ReadStereoImage(o.left);
  const cv::Mat right_image = ReadStereoImage(o.right);
  DenseStereoResult result = RunDenseStereo(left_image, right_image, left, right, o.stereo,
                                            MakeProgressBar(global, "stereo"));
  std::vector<SparseTiePoint> ties =
      o.tie_points ? MatchSparseTiePoints(result, o.stereo) : std::vector<SparseTiePoint>{};
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  size_t accepted_ties = 0;
  for (const SparseTiePoint& t : ties) accepted_ties += t.match.ok ? 1 : 0;
  return {std::move(left), std::move(right), std::move(result),
          std::move(ties), accepted_ties,    seconds};
}

// points.ply, disparity.png and, as asked, tie_points.csv and the rectified pair.
void WriteStereoProducts(const StereoCommandOptions& o, const StereoRun& run,
                         const OutputFolder& out) {
  const DenseStereoResult& result = run.result;
  WritePointCloudPly(result.cloud, out / "points.ply");
  cv::Mat quicklook;
  const DisparityResult& disparity = result.disparity;
  disparity.disparity.convertTo(
      quicklook, CV_8U, 254.0 / disparity.num_disparities,
      1.0 - 254.0 * disparity.min_disparity / disparity.num_disparities);  // NaN -> 0.
  WriteImage(out / "disparity.png", quicklook);
  if (o.tie_points) WriteFileAtomically(out / "tie_points.csv", TiePointsCsv(run.ties));
  if (o.write_rectified) {
    WriteImage(out / "left_rectified.png", result.disparity.left8);
    WriteImage(out / "right_rectified.png", result.disparity.right8);
  }
}

nlohmann::json StereoSummaryJson(const StereoCommandOptions& o, const StereoRun& run) {
  const DenseStereoResult& result = run.result;
  const DisparityResult& disparity = result.disparity;
  const DenseStereoSummary& m = result.summary;
  return {{"command", "stereo"},
          {"left", o.left},
          {"right", o.right},
          {"left_camera", run.left.source},
          {"right_camera", run.right.source},
          {"camera_model", run.left.model.TypeName()},
          {"frame", result.cloud.frame},
          {"site", result.cloud.site},
          {"camera_center_m",
           {result.cloud.camera_center.x(), result.cloud.camera_center.y(),
            result.cloud.camera_center.z()}},
          {"baseline_m", m.baseline_m},
          {"focal_px", m.focal_px},
          {"min_disparity", disparity.min_disparity},
          {"num_disparities", m.num_disparities},
          {"overlap_pixels", m.overlap_pixels},
          {"valid_pixels", m.valid_pixels},
          {"valid_fraction", m.valid_fraction},
          {"orientation_features", disparity.orientation_features},
          {"orientation_rms_px_before", disparity.orientation_rms_before_px},
          {"orientation_rms_px_after", disparity.orientation_rms_after_px},
          {"right_rotation_deg", disparity.right_rotation_deg},
          {"baseline_tilt_deg", disparity.baseline_tilt_deg},
          {"row_shift_features", disparity.row_shift_features},
          {"vertical_disparity_rms_px_before", disparity.row_shift_before_rms_px},
          {"vertical_disparity_rms_px_after", disparity.row_shift_rms_px},
          {"points", m.points},
          {"dropped_beyond_range", m.beyond_range},
          {"dropped_buried", m.line_of_sight.buried},
          {"dropped_floating", m.line_of_sight.floating},
          {"max_range_m", o.stereo.max_range_m},
          {"interest_points", run.ties.size()},
          {"tie_points", run.accepted_ties},
          {"seconds", run.seconds}};
}

void PrintStereoSummary(const StereoCommandOptions& o, const StereoRun& run,
                        const OutputFolder& out) {
  const DenseStereoSummary& m = run.result.summary;
  std::printf(
      "%zu points (%.1f%% of the overlap has a disparity), %zu beyond %.0f m, %zu buried under "
      "and %zu floating over the ground they see -> %s\n",
      m.points, 100.0 * m.valid_fraction, m.beyond_range, o.stereo.max_range_m,
      m.line_of_sight.buried, m.line_of_sight.floating, (out.final_dir() / "points.ply").c_str());
  if (o.tie_points) {
    std::printf("%zu of %zu Förstner points matched as tie points -> %s\n", run.accepted_ties,
                run.ties.size(), (out.final_dir() / "tie_points.csv").c_str());
  }
}

void RunStereoCommand(const StereoCommandOptions& o, const GlobalOptions& global) {
  const auto start = std::chrono::steady_clock::now();
  OutputFolder out(o.out, OutputPolicy(global, "stereo",
                                       {"points.ply", "disparity.png", "tie_points.csv",
                                        "left_rectified.png", "right_rectified.png"},
                                       {o.left, o.right, o.left_camera, o.right_camera}));
  const StereoRun run = ComputeStereo(o, global, start);
  // Everything computed: only now write (into the staging folder).
  WriteStereoProducts(o, run, out);
  WriteSummary(out.dir(), StereoSummaryJson(o, run));
  out.Commit();  // Also removes an earlier run's tie_points.csv or rectified pair.
  if (!global.quiet) PrintStereoSummary(o, run, out);
}

}  // namespace

void AddStereoCommand(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<StereoCommandOptions>();
  auto* cmd = app.add_subcommand(
      "stereo", "Dense stereo of a rectified pair into 3D points with covariance (points.ply)");
  cmd->footer(kStereoDetails);
  AddStereoOptions(cmd, *o);
  cmd->callback([o, &global] { RunStereoCommand(*o, global); });
}

}  // namespace areomap::cli
