// DTM gridding benchmark: areomap's GridPoints against gdal_grid (linear, and invdistnn — gdal's
// inverse distance with a nearest-neighbour search, the variant that, like ours, limits the
// search to a radius) on the same points and the same grid, run from this process.
//
//   build/release/bench/areomap_bench_dtm [points_per_site_step_rad]
//   build/release/bench/areomap_bench_dtm --demo-accuracy DTM.tif SITE   (see DemoAccuracyMain)
//   build/release/bench/areomap_bench_dtm --demo-ortho-accuracy ORTHO.tif SITE
//
// Points: a full Navcam-like panorama simulated from the generator's scene (viewshed, eq. 4.3
// noise), carried onto the site's local map; ~1 M points with the default 2e-3 rad step.
// Each job (ours and gdal_grid) runs as a child process that reads the same CSV, grids it and
// writes a GeoTIFF: wall time and peak resident memory (wait4's ru_maxrss) are measured the same
// way for both. Our gridding alone is also timed in-process (median of 3, TBB on all cores and on
// one). The outputs are compared cell by cell where both are known.
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include <tbb/global_control.h>
#include <tbb/info.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/dtm.h"
#include "areomap/map/error.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/raster.h"
#include "areomap/samples/mission.h"
#include "areomap/samples/orbital.h"
#include "areomap/samples/simulated_points.h"

namespace areomap {
namespace {

struct ChildResult {
  double wall_s = 0.0;
  double cpu_s = 0.0;
  double peak_mib = 0.0;
  int status = -1;
};

double Seconds(const timeval& t) {
  return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
}

double ProcessCpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return Seconds(usage.ru_utime) + Seconds(usage.ru_stime);
}

// Runs argv as a child process; its wall time and peak resident memory.
ChildResult RunChild(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    execvp(argv[0], argv.data());
    _exit(127);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  ChildResult r;
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.peak_mib = static_cast<double>(usage.ru_maxrss) / 1024.0;
  r.cpu_s = Seconds(usage.ru_utime) + Seconds(usage.ru_stime);
  r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::vector<GridPoint> ReadCsv(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // Header.
  std::vector<GridPoint> points;
  while (std::getline(in, line)) {
    GridPoint p;
    const char* c = line.data();
    const char* end = c + line.size();
    for (int k = 0; k < 3; ++k) {
      c = std::from_chars(c, end, p.xyz[k]).ptr + 1;
    }
    points.push_back(p);
  }
  return points;
}

GriddingOptions Options(const std::string& method) {
  GriddingOptions o;
  o.method = GriddingMethodFromString(method);
  o.max_edge_m = 1e9;  // gdal_grid's linear has no edge limit (radius=0: nodata outside the hull).
  o.idw_radius_m = 0.3;
  o.idw_max_points = 12;
  return o;
}

GridSpec ParseGrid(char** argv) {
  GridSpec g;
  g.x_left = std::stod(argv[0]);
  g.y_top = std::stod(argv[1]);
  g.posting = std::stod(argv[2]);
  g.width = std::stoi(argv[3]);
  g.height = std::stoi(argv[4]);
  return g;
}

// Child: areomap_bench_dtm --child METHOD CSV OUT x_left y_top posting width height
int ChildMain(char** argv) {
  const std::vector<GridPoint> points = ReadCsv(argv[1]);
  // All layers are computed; the elevation alone is written, as gdal_grid writes one band.
  const GriddedLayers layers = GridPoints(points, ParseGrid(argv + 3), Options(argv[0]));
  GeoRaster raster;
  raster.bands = {layers.elevation};
  raster.geotransform = layers.grid.Transform();
  raster.nodata = std::numeric_limits<double>::quiet_NaN();
  WriteGeoTiff(argv[2], raster);
  return 0;
}

struct Comparison {
  int both = 0, only_ours = 0, only_gdal = 0, within_mm = 0;
  double max_abs = 0.0, rms = 0.0;
};

// gdal_grid's output is read back and sampled at our cell centres.
Comparison Compare(const std::filesystem::path& ours_path, const std::filesystem::path& gdal_path,
                   const GridSpec& grid) {
  const RasterDataset ours_ds = RasterDataset::Open(ours_path);
  const RasterDataset gdal_ds = RasterDataset::Open(gdal_path);
  const cv::Mat ours = ours_ds.ReadWindowFloat(1, ours_ds.FullWindow());
  const cv::Mat gdal = gdal_ds.ReadWindowFloat(1, gdal_ds.FullWindow());
  const GeoTransform& t = *gdal_ds.info().geotransform;
  Comparison c;
  double squares = 0.0;
  for (int row = 0; row < grid.height; ++row) {
    for (int col = 0; col < grid.width; ++col) {
      const Eigen::Vector2d center = grid.CellCenter(col, row);
      const Eigen::Vector2d pixel = t.MapToPixel(center.x(), center.y());
      const int gc = static_cast<int>(std::floor(pixel.x())),
                gr = static_cast<int>(std::floor(pixel.y()));
      const float g = (gc >= 0 && gr >= 0 && gc < gdal.cols && gr < gdal.rows)
                          ? gdal.at<float>(gr, gc)
                          : std::numeric_limits<float>::quiet_NaN();
      const float o = ours.at<float>(row, col);
      const bool known_o = std::isfinite(o), known_g = std::isfinite(g);
      if (known_o && known_g) {
        ++c.both;
        c.max_abs = std::max(c.max_abs, static_cast<double>(std::abs(o - g)));
        c.within_mm += std::abs(o - g) <= 1e-3f ? 1 : 0;
        squares += static_cast<double>(o - g) * (o - g);
      } else if (known_o) {
        ++c.only_ours;
      } else if (known_g) {
        ++c.only_gdal;
      }
    }
  }
  c.rms = c.both > 0 ? std::sqrt(squares / c.both) : 0.0;
  return c;
}

struct InProcess {
  double wall_s = 0.0;
  double cpu_s = 0.0;
};

// Median of 3 of our gridding alone, wall and process CPU time.
InProcess MedianGridSeconds(const std::vector<GridPoint>& points, const GridSpec& grid,
                            const GriddingOptions& options, int threads) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                            static_cast<size_t>(threads));
  std::vector<double> times, cpu;
  for (int i = 0; i < 3; ++i) {
    const auto start = std::chrono::steady_clock::now();
    const double cpu_start = ProcessCpuSeconds();
    const GriddedLayers layers = GridPoints(points, grid, options);
    times.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    cpu.push_back(ProcessCpuSeconds() - cpu_start);
    if (layers.known_cells == 0) std::printf("warning: empty grid\n");
  }
  std::sort(times.begin(), times.end());
  std::sort(cpu.begin(), cpu.end());
  return {times[1], cpu[1]};
}

int BenchMain(const char* self, double step_rad) {
  // The points: a full panorama from the middle of a generator scene.
  SceneOptions scene_options;
  scene_options.half_extent_m = 96.0;
  scene_options.rock_path = {{-30.0, 0.0}, {30.0, 0.0}};
  const Scene scene(scene_options);
  SimulatedPointsOptions simulation;
  simulation.angular_step_rad = step_rad;
  const PointCloud cloud = SimulateSitePointCloud(scene, {0.0, 0.0}, 0, simulation);
  SceneGeoreference georef;
  georef.origin = {RadFromDeg(-14.5692), RadFromDeg(175.4729), scene.GroundHeightAt(0.0, 0.0)};
  const MapFrame map = MapFrame::LocalEquirectangular(georef.body, georef.origin);
  std::vector<GridPoint> points =
      PointsOnMap(cloud, SiteGeoreference::AtOrigin(georef.body, georef.origin), map);
  // The map's y is ~ -863 km here (equirectangular northing from the equator); qhull, which
  // gdal_grid's `linear` uses, loses precision on near-cocircular points at such offsets (10 mm
  // differences with the raw coordinates). Both tools get coordinates relative to the first
  // point.
  const Eigen::Vector2d shift = points.front().xyz.head<2>();
  for (GridPoint& p : points) p.xyz.head<2>() -= shift;
  Eigen::Vector2d min = points.front().xyz.head<2>(), max = min;
  for (const GridPoint& p : points) {
    min = min.cwiseMin(p.xyz.head<2>());
    max = max.cwiseMax(p.xyz.head<2>());
  }
  const GridSpec grid = GridSpec::Covering(min, max, 0.1);
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("areomap_dtm_bench_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream csv(dir / "points.csv");
    csv << "x,y,z\n";
    char line[96];
    for (const GridPoint& p : points) {
      std::snprintf(line, sizeof(line), "%.4f,%.4f,%.4f\n", p.xyz.x(), p.xyz.y(), p.xyz.z());
      csv << line;
    }
    std::ofstream vrt(dir / "points.vrt");
    vrt << "<OGRVRTDataSource><OGRVRTLayer name=\"points\"><SrcDataSource>"
        << (dir / "points.csv").string()
        << "</SrcDataSource><GeometryType>wkbPoint25D</GeometryType>"
        << "<GeometryField encoding=\"PointFromColumns\" x=\"x\" y=\"y\" z=\"z\"/>"
        << "</OGRVRTLayer></OGRVRTDataSource>\n";
  }
  // Both sides grid what is in the CSV (4 decimals).
  const std::vector<GridPoint> csv_points = ReadCsv(dir / "points.csv");
  std::printf("points: %zu (angular step %.1e rad), grid %d x %d at %.2f m (%d cells)\n",
              csv_points.size(), step_rad, grid.width, grid.height, grid.posting,
              grid.width * grid.height);
  const auto fmt = [](double v) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.10g", v);
    return std::string(b);
  };
  const std::string x_right = fmt(grid.x_left + grid.width * grid.posting);
  const std::string y_bottom = fmt(grid.y_top - grid.height * grid.posting);
  const int cores = tbb::info::default_concurrency();
  std::printf(
      "\n| method | areomap gridding, %d threads: wall (CPU) | points/s | 1 thread: wall | areomap "
      "job (read CSV, grid, write): wall (CPU) | peak | gdal_grid job: wall (CPU) | peak | "
      "speed-up, job wall (CPU) | speed-up, gridding vs gdal job, wall (CPU) | memory ratio | "
      "cells both / only ours / only gdal | within 1 mm | max abs diff | RMS diff |\n"
      "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|\n",
      cores);
  for (const std::string method : {"tin", "idw"}) {
    const GriddingOptions options = Options(method);
    const InProcess t_all = MedianGridSeconds(csv_points, grid, options, cores);
    const InProcess t_one = MedianGridSeconds(csv_points, grid, options, 1);
    const std::filesystem::path ours = dir / (method + "_ours.tif");
    const std::filesystem::path gdal = dir / (method + "_gdal.tif");
    const ChildResult ours_job =
        RunChild({self, "--child", method, (dir / "points.csv").string(), ours.string(),
                  fmt(grid.x_left), fmt(grid.y_top), fmt(grid.posting), std::to_string(grid.width),
                  std::to_string(grid.height)});
    const std::string algorithm =
        method == "tin" ? "linear:radius=0:nodata=nan"
                        : "invdistnn:power=2:radius=0.3:max_points=12:min_points=1:nodata=nan";
    const ChildResult gdal_job = RunChild({"gdal_grid",
                                           "-q",
                                           "-a",
                                           algorithm,
                                           "-txe",
                                           fmt(grid.x_left),
                                           x_right,
                                           "-tye",
                                           fmt(grid.y_top),
                                           y_bottom,
                                           "-outsize",
                                           std::to_string(grid.width),
                                           std::to_string(grid.height),
                                           "-ot",
                                           "Float32",
                                           "-of",
                                           "GTiff",
                                           "-l",
                                           "points",
                                           (dir / "points.vrt").string(),
                                           gdal.string()});
    if (ours_job.status != 0 || gdal_job.status != 0) {
      std::printf("a job failed: areomap %d, gdal_grid %d\n", ours_job.status, gdal_job.status);
      return 1;
    }
    const Comparison c = Compare(ours, gdal, grid);
    std::printf(
        "| %s | %.3f s (%.3f s) | %.2f M | %.3f s | %.2f s (%.2f s) | %.0f MiB | %.2f s (%.2f s) | "
        "%.0f MiB | %.1f× (%.1f×) | %.1f× (%.1f×) | %.2f | %d / %d / %d | %.2f %% | %.2e m | "
        "%.2e m |\n",
        method == "tin" ? "TIN linear vs gdal `linear`"
                        : "IDW (12 nearest in 0.3 m) vs gdal `invdistnn`",
        t_all.wall_s, t_all.cpu_s, static_cast<double>(csv_points.size()) / t_all.wall_s / 1e6,
        t_one.wall_s, ours_job.wall_s, ours_job.cpu_s, ours_job.peak_mib, gdal_job.wall_s,
        gdal_job.cpu_s, gdal_job.peak_mib, gdal_job.wall_s / ours_job.wall_s,
        gdal_job.cpu_s / ours_job.cpu_s, gdal_job.wall_s / t_all.wall_s,
        gdal_job.cpu_s / t_all.cpu_s, gdal_job.peak_mib / ours_job.peak_mib, c.both, c.only_ours,
        c.only_gdal, 100.0 * c.within_mm / std::max(c.both, 1), c.max_abs, c.rms);
  }
  std::filesystem::remove_all(dir);
  return 0;
}

// --demo-accuracy DTM.tif SITE: a DTM of the `demo` mission (seed 1, e.g. `areomap stereo` +
// `areomap dtm --poses truth`) against the scene's true heights, which are rebuilt here exactly
// as GenerateMission builds them; RMS error, RMS sigma and coverage per range bin from SITE.
struct DemoTruth {
  MissionOptions options = MissionOptions::Preset("demo");
  Traverse traverse =
      PlanTraverse(options.traverse, options.telemetry, options.scene.half_extent_m, options.seed);
  Scene scene = [this] {
    SceneOptions s = options.scene;
    s.seed = options.seed;
    for (const SitePose& p : traverse.truth)
      s.rock_path.emplace_back(p.position.y(), p.position.x());
    return Scene(s);
  }();
  SceneGeoreference georef{Body::Mars2000(),
                           {RadFromDeg(options.site_lat_deg), RadFromDeg(options.site_lon_deg),
                            scene.GroundHeightAt(0.0, 0.0)}};
  MapFrame map = MapFrame::LocalEquirectangular(georef.body, georef.origin);
  Eigen::Vector2d SiteEnu(int site) const {
    const SitePose& p = traverse.truth.at(static_cast<size_t>(site));
    return {p.position.y(), p.position.x()};
  }
  Eigen::Vector2d Enu(const Eigen::Vector2d& xy) const {
    return (georef.EnuFromMbf() * map.MbfFromMap({xy.x(), xy.y(), georef.origin.h})).head<2>();
  }
};

// --demo-ortho-accuracy ORTHO.tif SITE: an orthophoto of the demo mission against the scene's
// albedo: NCC of 2.4 m patches (±0.5 m search) at 3-15 m from SITE, shift of the peak.
int DemoOrthoAccuracyMain(const std::filesystem::path& ortho_path, int site) {
  const DemoTruth truth;
  const Orthophoto ortho = ReadOrthophoto(ortho_path);
  const Eigen::Vector2d site_enu = truth.SiteEnu(site);
  constexpr int kPatch = 24, kSearch = 5;
  const int half = kPatch / 2 + kSearch;
  std::vector<double> shifts;
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (int row = half; row + half < ortho.grid.height; row += kPatch / 2) {
    for (int col = half; col + half < ortho.grid.width; col += kPatch / 2) {
      const cv::Rect rect(col - kPatch / 2, row - kPatch / 2, kPatch, kPatch);
      if (cv::countNonZero(ortho.valid(rect)) < 0.9 * kPatch * kPatch) continue;
      const double range = (truth.Enu(ortho.grid.CellCenter(col, row)) - site_enu).norm();
      if (range < 3.0 || range > 15.0) continue;
      cv::Mat albedo(2 * half, 2 * half, CV_32F);
      for (int r = 0; r < 2 * half; ++r) {
        for (int c = 0; c < 2 * half; ++c) {
          const Eigen::Vector2d e =
              truth.Enu(ortho.grid.CellCenter(col - half + c, row - half + r));
          double sum = 0.0;
          for (int i = -1; i <= 1; ++i) {
            for (int j = -1; j <= 1; ++j) {
              const double step = ortho.grid.posting / 3.0;
              sum += truth.scene.AlbedoAt(e.x() + i * step, e.y() + j * step) / 9.0;
            }
          }
          albedo.at<float>(r, c) = static_cast<float>(sum);
        }
      }
      cv::Mat patch = ortho.image(rect).clone(), score;
      patch.setTo(cv::mean(patch, ortho.valid(rect))[0], ortho.valid(rect) == 0);
      cv::matchTemplate(albedo, patch, score, cv::TM_CCOEFF_NORMED);
      double peak = 0.0;
      cv::Point at;
      cv::minMaxLoc(score, nullptr, &peak, nullptr, &at);
      if (peak < 0.3) continue;
      const Eigen::Vector2d shift(at.x - kSearch, at.y - kSearch);
      shifts.push_back(shift.norm());
      mean += shift;
    }
  }
  if (shifts.empty()) {
    std::printf("no patch could be located\n");
    return 1;
  }
  std::sort(shifts.begin(), shifts.end());
  double squared = 0.0;
  int within = 0;
  for (const double s : shifts) {
    squared += s * s;
    within += s < 2.0 ? 1 : 0;
  }
  mean /= static_cast<double>(shifts.size());
  std::printf(
      "%zu patches 3-15 m: RMS shift %.2f px, median %.2f px, %.0f %% under 2 px, mean (%.2f, "
      "%.2f) px, ground pixel %.2f m\n",
      shifts.size(), std::sqrt(squared / static_cast<double>(shifts.size())),
      shifts[shifts.size() / 2], 100.0 * within / static_cast<double>(shifts.size()), mean.x(),
      mean.y(), ortho.grid.posting);
  return 0;
}

int DemoAccuracyMain(const std::filesystem::path& dtm_path, int site) {
  const DemoTruth truth;
  const Scene& scene = truth.scene;
  const SceneGeoreference& georef = truth.georef;
  const MapFrame& map = truth.map;
  const Rigid3d enu_from_mbf = georef.EnuFromMbf();
  const Eigen::Vector2d site_enu = truth.SiteEnu(site);
  const Dtm dtm = ReadDtm(dtm_path);
  const GriddedLayers& l = dtm.layers;
  constexpr std::array<double, 5> edges{0.0, 5.0, 10.0, 15.0, 25.0};
  std::array<double, 4> squared_error{}, squared_sigma{};
  std::array<int, 4> known{}, area{}, outliers{};
  for (int row = 0; row < l.grid.height; ++row) {
    for (int col = 0; col < l.grid.width; ++col) {
      const Eigen::Vector2d xy = l.grid.CellCenter(col, row);
      const float z = l.elevation.at<float>(row, col);
      const Eigen::Vector3d enu =
          enu_from_mbf * map.MbfFromMap({xy.x(), xy.y(), std::isfinite(z) ? z : georef.origin.h});
      const double range = (enu.head<2>() - site_enu).norm();
      if (range >= edges.back()) continue;
      const size_t bin = static_cast<size_t>(std::upper_bound(edges.begin(), edges.end(), range) -
                                             edges.begin() - 1);
      ++area[bin];
      if (!std::isfinite(z)) continue;
      const double error = z - scene.HeightAt(enu.x(), enu.y());
      const double sigma = l.sigma.at<float>(row, col);
      ++known[bin];
      squared_error[bin] += error * error;
      squared_sigma[bin] += sigma * sigma;
      outliers[bin] += std::abs(error) > 3.0 * sigma ? 1 : 0;
    }
  }
  std::printf(
      "| range | cells known | coverage of the disc | RMS error | RMS sigma | ratio | |error| > 3 "
      "sigma |\n|---|---:|---:|---:|---:|---:|---:|\n");
  for (size_t b = 0; b < 4; ++b) {
    const int n = std::max(known[b], 1);
    std::printf("| %.0f-%.0f m | %d | %.1f %% | %.4f m | %.4f m | %.2f | %.1f %% |\n", edges[b],
                edges[b + 1], known[b], 100.0 * known[b] / std::max(area[b], 1),
                std::sqrt(squared_error[b] / n), std::sqrt(squared_sigma[b] / n),
                std::sqrt(squared_error[b] / std::max(squared_sigma[b], 1e-30)),
                100.0 * outliers[b] / n);
  }
  return 0;
}

}  // namespace
}  // namespace areomap

int main(int argc, char** argv) {
  try {
    if (argc >= 10 && std::string(argv[1]) == "--child") return areomap::ChildMain(argv + 2);
    if (argc == 4 && std::string(argv[1]) == "--demo-ortho-accuracy") {
      return areomap::DemoOrthoAccuracyMain(argv[2], std::stoi(argv[3]));
    }
    if (argc == 4 && std::string(argv[1]) == "--demo-accuracy") {
      return areomap::DemoAccuracyMain(argv[2], std::stoi(argv[3]));
    }
    const double step = argc >= 2 ? std::stod(argv[1]) : 2e-3;
    return areomap::BenchMain("/proc/self/exe", step);
  } catch (const areomap::Error& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
