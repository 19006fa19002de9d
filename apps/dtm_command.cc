// areomap dtm CLOUD.ply... --out DIR: stereo point clouds (areomap stereo) of one or more sites
// gridded into a DTM GeoTIFF (dtm.tif: elevation, count, stddev, propagated sigma) on the
// mission's local map (equirectangular on the local-radius sphere at the origin) or any Mars CRS.
#include <algorithm>
#include <filesystem>
#include <iostream>
#include <map>
#include <string>
#include <vector>

#include "areomap/map/crs.h"
#include "areomap/map/dtm.h"
#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/point_cloud_io.h"
#include "commands.h"

namespace areomap::cli {
namespace {

struct DtmCommandOptions {
  std::vector<std::string> clouds;
  std::string out, mission, poses = "telemetry", crs, method = "tin";
  std::vector<double> origin;                        // lat [deg], lon [deg], h [m]
  std::vector<double> site_position{0.0, 0.0, 0.0};  // With --origin: the site in site 0's frame.
  DtmOptions dtm;
};

// Site positions in site 0's frame and the mission origin, from --mission or --origin.
struct Georeference {
  Body body = Body::Mars2000();
  Geographic origin;
  std::map<int, Eigen::Vector3d> site_positions;  // Empty: every cloud at --site-position.
  // Rotation about the site's z (down) taking the frame the clouds were made in (the labels'
  // telemetry heading) to the chosen poses' heading [rad]; 0 for telemetry poses.
  std::map<int, double> heading_corrections;
};

Georeference ReadGeoreference(const DtmCommandOptions& o) {
  Georeference g;
  if (!o.mission.empty()) {
    const MissionManifest manifest = ReadMissionManifest(o.mission);
    g.body = manifest.body;
    g.origin = manifest.origin;
    if (o.poses != "telemetry" && o.poses != "truth") {
      throw Error("--poses: expected telemetry or truth, got '" + o.poses + "'");
    }
    const std::vector<MissionSitePose>& poses =
        o.poses == "truth" ? manifest.truth_sites : manifest.telemetry;
    if (poses.empty()) throw Error(o.mission + ": the mission has no " + o.poses + " site poses");
    for (const MissionSitePose& p : poses) g.site_positions[p.site] = p.position;
    for (const MissionSitePose& p : manifest.telemetry) {
      g.heading_corrections[p.site] = o.poses == "truth" ? -p.heading : 0.0;
    }
    if (o.poses == "truth") {
      for (const MissionSitePose& p : poses) g.heading_corrections[p.site] += p.heading;
    }
    return g;
  }
  if (o.origin.size() != 3)
    throw Error("give the site poses with --mission DIR or --origin LAT,LON,H");
  // Checked while parsing (CheckLatLonHeight).
  g.origin = {RadFromDeg(o.origin[0]), RadFromDeg(o.origin[1]), o.origin[2]};
  return g;
}

}  // namespace

// What `areomap dtm --help` and docs/cli.md say about the command beyond its options.
constexpr const char* kDtmDetails =
    "Grids stereo point clouds (`areomap stereo`) of one or more sites into `dtm.tif` (elevation,\n"
    "point count, standard deviation, propagated 1σ; nodata NaN) on the mission's local map\n"
    "(equirectangular on the local-radius sphere at the origin, as HiRISE RDRs) or `--crs` any\n"
    "projected Mars CRS. `--method tin|mean|max|idw`, `--posting`, `--max-edge` (TIN gaps).";

namespace {

void AddDtmOptions(CLI::App* cmd, DtmCommandOptions& o) {
  cmd->add_option("clouds", o.clouds, "Point clouds (PLY from areomap stereo), site frames")
      ->required();
  cmd->add_option("--out", o.out, "Output folder (created if needed)")->required();
  cmd->add_option("--mission", o.mission,
                  "Mission folder: origin and site poses (each cloud's site selects its pose); "
                  "instead of --origin and --site-position");
  cmd->add_option("--poses", o.poses,
                  "With --mission: site poses telemetry or truth (truth also turns each cloud "
                  "by the heading the labels' telemetry got wrong)")
      ->capture_default_str();
  CheckLatLonHeight(
      cmd->add_option(
             "--origin", o.origin,
             "Without --mission: site 0's origin, planetocentric lat, east lon [deg], h [m]")
          ->expected(3)
          ->delimiter(','));
  cmd->add_option("--site-position", o.site_position,
                  "With --origin: the clouds' site origin in site 0's frame, north,east,down [m]")
      ->expected(3)
      ->delimiter(',')
      ->check(FiniteNumber())
      ->capture_default_str();
  cmd->add_option("--crs", o.crs,
                  "Projected Mars CRS of the DTM (e.g. IAU_2015:49910); default: equirectangular "
                  "on the local-radius sphere at the origin");
  cmd->add_option("--posting", o.dtm.posting_m, "Cell size [m]")
      ->check(NumberIn(0.0, 100.0, Bound::kOpen))
      ->capture_default_str();
  cmd->add_option("--method", o.method, "tin, mean, max or idw")->capture_default_str();
  cmd->add_option("--max-edge", o.dtm.gridding.max_edge_m,
                  "TIN: longest triangle edge not taken for a gap [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--max-edge-per-range", o.dtm.gridding.max_edge_per_range,
                  "TIN: the edge limit grows by this much per metre of range [m/m]")
      ->check(NumberIn(0.0, 10.0, Bound::kClosed, Bound::kOpen))
      ->capture_default_str();
  cmd->add_option("--idw-radius", o.dtm.gridding.idw_radius_m, "IDW: search radius [m]")
      ->check(PositiveNumber())
      ->capture_default_str();
  cmd->add_option("--idw-points", o.dtm.gridding.idw_max_points, "IDW: nearest points used")
      ->check(IntegerAtLeast(1))
      ->capture_default_str();
}

// The mission gives the origin and every site's pose: --origin and --site-position would be
// ignored beside it, and --poses means nothing without it.
void CheckDtmPoseSource(const DtmCommandOptions& o, const CLI::App& cmd) {
  if (!o.mission.empty() && (cmd.count("--origin") > 0 || cmd.count("--site-position") > 0)) {
    throw Error(
        "--mission gives the origin and each cloud's site pose: leave out --origin and "
        "--site-position, or give them without --mission");
  }
  if (o.mission.empty() && cmd.count("--poses") > 0) {
    throw Error("--poses chooses the mission's site poses: it needs --mission");
  }
}

// Each cloud with its site's pose: from the mission by the cloud's site, else --site-position.
std::vector<SiteCloud> PlaceSiteClouds(const std::vector<PointCloud>& clouds, const Georeference& g,
                                       const DtmCommandOptions& o) {
  std::vector<SiteCloud> sites;
  for (size_t i = 0; i < clouds.size(); ++i) {
    Eigen::Vector3d position(o.site_position[0], o.site_position[1], o.site_position[2]);
    double heading_correction = 0.0;
    if (!g.site_positions.empty()) {
      const auto correction = g.heading_corrections.find(clouds[i].site);
      if (correction != g.heading_corrections.end()) heading_correction = correction->second;
      const auto it = g.site_positions.find(clouds[i].site);
      if (it == g.site_positions.end()) {
        throw Error(o.clouds[i] + ": site " + std::to_string(clouds[i].site) + " has no pose in " +
                    o.mission);
      }
      position = it->second;
    }
    sites.push_back({&clouds[i], SiteGeoreference::InMission(
                                     g.body, g.origin,
                                     Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(
                                                 heading_correction, Eigen::Vector3d::UnitZ())),
                                             position))});
  }
  return sites;
}

// Median and 90th percentile of the propagated sigma over the known cells [m] (0 if none).
struct DtmSigmaStats {
  double median_m = 0.0;
  double p90_m = 0.0;
};

DtmSigmaStats SigmaStats(const Dtm& dtm) {
  std::vector<float> sigmas;
  for (int row = 0; row < dtm.layers.grid.height; ++row) {
    for (int col = 0; col < dtm.layers.grid.width; ++col) {
      const float s = dtm.layers.sigma.at<float>(row, col);
      if (std::isfinite(s)) sigmas.push_back(s);
    }
  }
  std::sort(sigmas.begin(), sigmas.end());
  const auto percentile = [&](double q) {
    return sigmas.empty()
               ? 0.0
               : static_cast<double>(
                     sigmas[static_cast<size_t>(q * static_cast<double>(sigmas.size() - 1))]);
  };
  return {percentile(0.5), percentile(0.9)};
}

nlohmann::json DtmSummaryJson(const DtmCommandOptions& o, const Dtm& dtm, size_t points,
                              const DtmSigmaStats& sigma) {
  const GridSpec& grid = dtm.layers.grid;
  const double cells = static_cast<double>(grid.width) * grid.height;
  return {{"command", "dtm"},
          {"dtm", "dtm.tif"},
          {"clouds", o.clouds},
          {"points", points},
          {"method", o.method},
          {"posting_m", grid.posting},
          {"width", grid.width},
          {"height", grid.height},
          {"known_cells", dtm.layers.known_cells},
          {"coverage", dtm.layers.known_cells / cells},
          {"sigma_median_m", sigma.median_m},
          {"sigma_p90_m", sigma.p90_m}};
}

void RunDtmCommand(const DtmCommandOptions& o, const GlobalOptions& global) {
  DtmOptions options = o.dtm;
  options.gridding.method = GriddingMethodFromString(o.method);
  options.Check();
  std::vector<std::filesystem::path> inputs(o.clouds.begin(), o.clouds.end());
  inputs.push_back(o.mission);
  OutputFolder out(o.out, OutputPolicy(global, "dtm", {"dtm.tif"}, inputs));
  const ProgressCallback progress = MakeProgressBar(global, "dtm");
  const Georeference g = ReadGeoreference(o);
  std::vector<PointCloud> clouds;
  for (const std::string& path : o.clouds) {
    clouds.push_back(ReadPointCloudPly(path));
    CheckPointCloud(clouds.back(), path);
  }
  const std::vector<SiteCloud> sites = PlaceSiteClouds(clouds, g, o);
  const MapFrame map = o.crs.empty() ? MapFrame::LocalEquirectangular(g.body, g.origin)
                                     : MapFrame::FromCrs(g.body, Crs::FromUserInput(o.crs));
  const Dtm dtm = MakeDtm(sites, map, options, progress);
  WriteDtm(out / "dtm.tif", dtm);
  size_t points = 0;
  for (const PointCloud& c : clouds) points += c.points.size();
  const DtmSigmaStats sigma = SigmaStats(dtm);
  WriteSummary(out.dir(), DtmSummaryJson(o, dtm, points, sigma));
  out.Commit();
  if (!global.quiet) {
    const GridSpec& grid = dtm.layers.grid;
    std::cout << "wrote " << (out.final_dir() / "dtm.tif").string() << " (" << grid.width << " x "
              << grid.height << " at " << grid.posting << " m, " << dtm.layers.known_cells
              << " cells known, median sigma " << sigma.median_m << " m)\n";
  }
}

}  // namespace

void AddDtmCommand(CLI::App& app, const GlobalOptions& global) {
  auto o = std::make_shared<DtmCommandOptions>();
  auto* cmd = app.add_subcommand(
      "dtm", "Grid stereo point clouds (areomap stereo) of one or more sites into a DTM GeoTIFF");
  cmd->footer(kDtmDetails);
  AddDtmOptions(cmd, *o);
  cmd->callback([o, cmd, &global] {
    CheckDtmPoseSource(*o, *cmd);
    RunDtmCommand(*o, global);
  });
}

}  // namespace areomap::cli
