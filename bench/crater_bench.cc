// Crater detection speed and quality on a large generated tile, against OpenCV's HoughCircles on
// the same image in the same run. Usage:
//   areomap_bench_crater [SIZE_PX [UPSAMPLE [SHADING [SAMPLES]]]]
// (default 4000 1 1 float32; UPSAMPLE 0 skips the 2x upsampled level for craters under 16 px,
// 1 searches it around small full-resolution arcs (the default options) and also runs the
// whole-level search of 2 as a baseline in the same process, 2 searches all of it; SHADING 0 the
// bowl-shading template hypotheses; SAMPLES float32 or uint16, the GeoTIFF's sample type: Float32
// as areomap's own products, deflate with the floating-point predictor; UInt16 as HiRISE or CTX
// images, deflate with horizontal differencing, the scene rounded to integers).
//
// For profiling the detection alone (callgrind, perf, alternated runs of two builds on the same
// file):
//   areomap_bench_crater write SIZE_PX PATH [SAMPLES]   the tile as a GeoTIFF at PATH, truth at
//                                                       PATH.csv
//   areomap_bench_crater detect PATH [RUNS [UPSAMPLE]]   DetectCratersInRaster on PATH (templates
//                                             off; the upsampled level off unless UPSAMPLE is 1
//                                             (around small arcs) or 2 (all of it)),
//                                             scored against PATH.csv if present
//   areomap_bench_crater upsample [SIDE_PX [RUNS]]   the detector's 2x upsampling of one
//                                             SIDE_PX^2 tile (default 2304, a padded tile) on
//                                             one thread: UpsampleTwice against cv::resize
//                                             INTER_LINEAR, the same values checked
//
// The tile holds bowls lit from the east (bright western wall, dark eastern wall, sharp rim,
// 12-120 px across, log-uniform) on a textured plain with noise; truth is exact. areomap runs end
// to end from a GeoTIFF on disk (tiled windowed reads, TBB over tiles); HoughCircles gets the
// 8-bit image in memory (its time excludes reading). Both are scored with the same rule
// (crater_score.h).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/info.h>
#include <opencv2/imgproc.hpp>

#include "areomap/crater/crater_raster.h"
#include "areomap/crater/crater_score.h"
#include "areomap/crater/upsample.h"

namespace {

using areomap::CraterCircle;

cv::Mat DrawScene(int size, std::vector<CraterCircle>* truth) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  cv::Mat texture(size / 8 + 1, size / 8 + 1, CV_32F);
  cv::randn(texture, 0.0, 25.0);
  cv::Mat image;
  cv::resize(texture, image, cv::Size(size, size), 0, 0, cv::INTER_CUBIC);
  image += 400.0;
  const int wanted = size * size / 40000;  // one crater per 200 x 200 px
  for (int attempt = 0; attempt < wanted * 20 && static_cast<int>(truth->size()) < wanted;
       ++attempt) {
    const double d = std::exp(std::log(12.0) + (std::log(120.0) - std::log(12.0)) * unit(rng));
    const Eigen::Vector2d c(d + (size - 2 * d) * unit(rng), d + (size - 2 * d) * unit(rng));
    bool overlaps = false;
    for (const CraterCircle& o : *truth) {
      overlaps |= (o.center - c).norm() < 0.7 * (o.diameter + d);
    }
    if (!overlaps) truth->push_back({c, d});
  }
  for (const CraterCircle& c : *truth) {
    const double r = 0.5 * c.diameter;
    for (int y = static_cast<int>(c.center.y() - r); y <= static_cast<int>(c.center.y() + r); ++y) {
      for (int x = static_cast<int>(c.center.x() - r); x <= static_cast<int>(c.center.x() + r);
           ++x) {
        const double dx = x + 0.5 - c.center.x(), dy = y + 0.5 - c.center.y();
        const double rho = std::hypot(dx, dy) / r;
        if (rho < 1.0) image.at<float>(y, x) += static_cast<float>(-300.0 * (dx / r) * rho);
      }
    }
  }
  cv::GaussianBlur(image, image, cv::Size(), 0.7);
  cv::Mat noise(image.size(), CV_32F);
  cv::randn(noise, 0.0, 4.0);
  return image + noise;
}

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// CPU time of the whole process (all threads) [s]: on a machine shared with other jobs the wall
// time depends on their load, CPU time much less.
double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

// The bench's detector options; `upsample` (0, 1, 2) and `shading` as the command line says.
areomap::CraterDetectorOptions BenchOptions(int upsample, bool shading) {
  areomap::CraterDetectorOptions options;
  options.method = areomap::CraterMethod::kEdges;
  options.sun_azimuth_deg = 90.0;
  options.min_diameter_px = 10.0;
  options.upsample_small_craters = upsample != 0;
  options.upsample_only_around_small_arcs = upsample != 2;
  options.shading_template.enabled = shading;
  return options;
}

const std::vector<double> kBins = {12.0, 24.0, 48.0, 1e9};

// Precision, recall and F1 of `found` against `truth` by the bench's diameter bins.
areomap::CraterScore ScoreDetections(const std::vector<CraterCircle>& truth,
                                     const std::vector<areomap::CraterDetection>& found) {
  return areomap::ScoreCraters(truth, areomap::CirclesOf(found), kBins);
}

// The GeoTIFF sample type named `samples` ("float32" or "uint16") as a cv::Mat depth.
int SampleDepth(const std::string& samples) {
  if (samples == "float32") return CV_32F;
  if (samples == "uint16") return CV_16U;
  throw std::invalid_argument("sample type '" + samples + "': expected float32 or uint16");
}

// Writes `image` as a GeoTIFF of sample depth `depth` (areomap's compression and predictors).
void WriteScene(const cv::Mat& image, int depth, const std::filesystem::path& path) {
  areomap::GeoRaster raster;
  image.convertTo(raster.bands.emplace_back(), depth);  // rounded and saturated to integers
  areomap::WriteGeoTiff(path, raster);
}

int WriteTile(int size, const std::filesystem::path& path, int depth) {
  std::vector<CraterCircle> truth;
  WriteScene(DrawScene(size, &truth), depth, path);
  std::ofstream csv(path.string() + ".csv");
  csv.precision(17);
  csv << "x_px,y_px,diameter_px\n";
  for (const CraterCircle& c : truth) {
    csv << c.center.x() << ',' << c.center.y() << ',' << c.diameter << '\n';
  }
  std::printf("wrote %s (%d x %d px, %zu craters) and %s.csv\n", path.c_str(), size, size,
              truth.size(), path.c_str());
  return csv ? 0 : 1;
}

int DetectOnly(const std::filesystem::path& path, int runs, int upsample) {
  const std::filesystem::path truth_path = path.string() + ".csv";
  const bool scored = std::filesystem::exists(truth_path);
  const std::vector<CraterCircle> truth =
      scored ? areomap::ReadCraterCsv(truth_path) : std::vector<CraterCircle>{};
  for (int run = 0; run < runs; ++run) {
    const double cpu_start = CpuSeconds();
    const auto start = std::chrono::steady_clock::now();
    const areomap::RasterDataset dataset = areomap::RasterDataset::Open(path);
    const auto found = areomap::DetectCratersInRaster(dataset, areomap::RimSource::kImage,
                                                      BenchOptions(upsample, false));
    const double wall = Seconds(start), cpu = CpuSeconds() - cpu_start;
    const double megapixels =
        static_cast<double>(dataset.info().width) * dataset.info().height / 1e6;
    std::printf("detect %s: wall %.3f s, cpu %.3f s, %.2f MP/s, %zu craters", path.c_str(), wall,
                cpu, megapixels / wall, found.size());
    if (scored) {
      const auto score = ScoreDetections(truth, found);
      std::printf(", P %.4f R %.4f F1 %.4f", score.all.precision, score.all.recall, score.all.f1);
    }
    std::printf("\n");
  }
  return 0;
}

// The default mode: areomap and HoughCircles on one generated tile (usage at the top).
int CompareWithHough(int argc, char** argv) {
  const int size = argc > 1 ? std::stoi(argv[1]) : 4000;
  const std::string samples = argc > 4 ? argv[4] : "float32";
  std::vector<CraterCircle> truth;
  const cv::Mat image = DrawScene(size, &truth);
  const auto path = std::filesystem::temp_directory_path() / "areomap_crater_bench.tif";
  WriteScene(image, SampleDepth(samples), path);
  const double megapixels = static_cast<double>(size) * size / 1e6;

  double cpu_start = CpuSeconds();
  auto start = std::chrono::steady_clock::now();
  const areomap::RasterDataset dataset = areomap::RasterDataset::Open(path);
  const int upsample = argc > 2 ? std::stoi(argv[2]) : 1;
  const bool shading = argc > 3 && std::stoi(argv[3]) != 0;
  const auto found = areomap::DetectCratersInRaster(dataset, areomap::RimSource::kImage,
                                                    BenchOptions(upsample, shading));
  const double ours_s = Seconds(start);
  const double ours_cpu = CpuSeconds() - cpu_start;
  const auto ours_score = ScoreDetections(truth, found);

  // The learned detector (--method learned) on the same file.
  cpu_start = CpuSeconds();
  start = std::chrono::steady_clock::now();
  areomap::CraterDetectorOptions learned_options;
  learned_options.method = areomap::CraterMethod::kLearned;
  learned_options.min_diameter_px = 10.0;
  const auto learned_found = areomap::DetectCratersInRaster(
      areomap::RasterDataset::Open(path), areomap::RimSource::kImage, learned_options);
  const double learned_s = Seconds(start);
  const double learned_cpu = CpuSeconds() - cpu_start;

  // The default of `areomap craters` on images (--method combined): both of the above, merged.
  cpu_start = CpuSeconds();
  start = std::chrono::steady_clock::now();
  areomap::CraterDetectorOptions combined_options = BenchOptions(upsample, shading);
  combined_options.method = areomap::CraterMethod::kCombined;
  const auto combined_found = areomap::DetectCratersInRaster(
      areomap::RasterDataset::Open(path), areomap::RimSource::kImage, combined_options);
  const double combined_s = Seconds(start);
  const double combined_cpu = CpuSeconds() - cpu_start;

  // The upsampled level searched everywhere (the default options before it was searched only
  // around small arcs), on the same file.
  double whole_level_s = 0.0, whole_level_cpu = 0.0;
  std::vector<areomap::CraterDetection> whole_level_found;
  if (upsample == 1) {
    cpu_start = CpuSeconds();
    start = std::chrono::steady_clock::now();
    whole_level_found = areomap::DetectCratersInRaster(
        areomap::RasterDataset::Open(path), areomap::RimSource::kImage, BenchOptions(2, shading));
    whole_level_s = Seconds(start);
    whole_level_cpu = CpuSeconds() - cpu_start;
  }

  cv::Mat gray;
  cv::normalize(image, gray, 0, 255, cv::NORM_MINMAX, CV_8U);
  cpu_start = CpuSeconds();
  start = std::chrono::steady_clock::now();
  std::vector<cv::Vec3f> circles;
  cv::Mat blurred;
  cv::GaussianBlur(gray, blurred, cv::Size(), 1.0);
  cv::HoughCircles(blurred, circles, cv::HOUGH_GRADIENT, 1.0, 8.0, 100, 20, 5, 60);
  const double hough_s = Seconds(start);
  const double hough_cpu = CpuSeconds() - cpu_start;
  std::vector<CraterCircle> hough;
  for (const cv::Vec3f& c : circles) {
    // OpenCV's pixel centres are integers; GDAL's are at +0.5.
    hough.push_back({{c[0] + 0.5, c[1] + 0.5}, 2.0 * c[2]});
  }
  const auto hough_score = areomap::ScoreCraters(truth, hough, kBins);

  std::printf(
      "crater bench: %d x %d px (%.1f MP, %s GeoTIFF), %zu true craters 12-120 px, %d "
      "threads\n",
      size, size, megapixels, samples.c_str(), truth.size(), tbb::info::default_concurrency());
  const int threads = tbb::info::default_concurrency();
  std::printf("%-22s %8s %8s %8s %11s %9s %7s %7s %7s\n", "method", "wall_s", "MP/s", "cpu_s",
              "MP/cpu_s", "precision", "recall", "F1", "det");
  const auto row = [&](const char* name, double wall, double cpu, const areomap::CraterScore& score,
                       size_t count) {
    std::printf("%-22s %8.2f %8.2f %8.2f %11.2f %9.3f %7.3f %7.3f %7zu\n", name, wall,
                megapixels / wall, cpu, megapixels / cpu, score.all.precision, score.all.recall,
                score.all.f1, count);
  };
  row("areomap combined", combined_s, combined_cpu, ScoreDetections(truth, combined_found),
      combined_found.size());
  row("areomap learned", learned_s, learned_cpu, ScoreDetections(truth, learned_found),
      learned_found.size());
  row("areomap edges", ours_s, ours_cpu, ours_score, found.size());
  if (upsample == 1) {
    row("  upsampled everywhere", whole_level_s, whole_level_cpu,
        ScoreDetections(truth, whole_level_found), whole_level_found.size());
  }
  row("cv::HoughCircles", hough_s, hough_cpu, hough_score, hough.size());
  std::printf("time ratio areomap edges / HoughCircles: wall %.2f, cpu %.2f\n", ours_s / hough_s,
              ours_cpu / hough_cpu);
  std::printf("time ratio areomap learned / HoughCircles: wall %.2f, cpu %.2f\n",
              learned_s / hough_s, learned_cpu / hough_cpu);
  std::printf("time ratio areomap combined / HoughCircles: wall %.2f, cpu %.2f\n",
              combined_s / hough_s, combined_cpu / hough_cpu);
  if (upsample == 1) {
    std::printf("time ratio upsampled around small arcs / everywhere: wall %.2f, cpu %.2f\n",
                ours_s / whole_level_s, ours_cpu / whole_level_cpu);
  }
  std::printf("areomap throughput with %d threads fully busy (MP per cpu_s x %d): %.2f MP/s\n",
              threads, threads, megapixels / ours_cpu * threads);
  std::filesystem::remove(path);
  return 0;
}

// The upsampled level's resize of one tile, single-threaded as in a tile task (both
// implementations otherwise split rows over threads), alternated `runs` times.
int CompareUpsampling(int side, int runs) {
  cv::Mat tile(side, side, CV_32F);
  cv::randu(tile, 0.0, 4095.0);
  cv::Mat ours(2 * side, 2 * side, CV_32F), opencv(2 * side, 2 * side, CV_32F);
  ours.setTo(0.0);  // pages faulted in before timing, as the detector's scratch is
  opencv.setTo(0.0);
  const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
  const int opencv_threads = cv::getNumThreads();
  cv::setNumThreads(1);
  std::vector<double> ours_s, opencv_s;
  for (int run = 0; run < runs; ++run) {
    auto start = std::chrono::steady_clock::now();
    cv::resize(tile, opencv, opencv.size(), 0, 0, cv::INTER_LINEAR);
    opencv_s.push_back(Seconds(start));
    start = std::chrono::steady_clock::now();
    areomap::UpsampleTwice(tile, &ours);
    ours_s.push_back(Seconds(start));
  }
  cv::setNumThreads(opencv_threads);
  const int differing = cv::countNonZero(ours != opencv);
  std::sort(ours_s.begin(), ours_s.end());
  std::sort(opencv_s.begin(), opencv_s.end());
  const double ours_median = ours_s[ours_s.size() / 2],
               opencv_median = opencv_s[opencv_s.size() / 2];
  std::printf(
      "upsample %d^2 -> %d^2 px, 1 thread, %d runs: UpsampleTwice median %.2f ms, "
      "cv::resize median %.2f ms, ratio %.2f; pixels differing: %d\n",
      side, 2 * side, runs, 1e3 * ours_median, 1e3 * opencv_median, opencv_median / ours_median,
      differing);
  return differing == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  try {
    if (mode == "write" && (argc == 4 || argc == 5)) {
      return WriteTile(std::stoi(argv[2]), argv[3], SampleDepth(argc == 5 ? argv[4] : "float32"));
    }
    if (mode == "detect" && argc >= 3 && argc <= 5) {
      return DetectOnly(argv[2], argc >= 4 ? std::stoi(argv[3]) : 1,
                        argc == 5 ? std::stoi(argv[4]) : 0);
    }
    if (mode == "upsample" && argc <= 4) {
      return CompareUpsampling(argc >= 3 ? std::stoi(argv[2]) : 2304,
                               argc == 4 ? std::stoi(argv[3]) : 9);
    }
    return CompareWithHough(argc, argv);
  } catch (const std::exception& error) {
    const bool named = mode == "write" || mode == "detect" || mode == "upsample";
    std::fprintf(stderr, "areomap_bench_crater%s%s: %s\n", named ? " " : "",
                 named ? mode.c_str() : "", error.what());
    return 1;
  }
}
