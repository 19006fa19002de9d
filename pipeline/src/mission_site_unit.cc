// One site of a mission run: dense stereo of every pair into one site cloud, the site's DTM and
// orthophoto on the mission map at the telemetry pose, and the orthophoto's registration onto
// the orbital image, which yields the site's control points.
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/map/atomic_file.h"
#include "areomap/map/camera_models.h"
#include "areomap/map/dense_stereo.h"
#include "areomap/map/error.h"
#include "areomap/map/image_io.h"
#include "areomap/map/point_cloud_io.h"
#include "areomap/registration/orbital_image.h"
#include "areomap/registration/ortho_registration.h"
#include "mission_units.h"

namespace areomap::mission_run {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct SiteStereo {
  PointCloud cloud;
  std::vector<OrthoSourceImage> images;  // Left images with their cameras in the site frame.
  std::vector<StereoPairRecord> pairs;
  size_t coarse_points_dropped = 0;  // Where a more precise pair saw the same ground.
};

std::string SiteName(int site) { return "site " + std::to_string(site); }

// The CAHV(OR) camera of a label moved into its site frame (orthophotos need CAHV/CAHVOR).
CahvorModel CameraInSite(const CameraFile& camera) {
  const auto* cahvor = std::get_if<CahvorModel>(&camera.model.variant());
  if (cahvor == nullptr) {
    throw Error(camera.source + ": the orthophoto needs a CAHV or CAHVOR model, not " +
                camera.model.TypeName());
  }
  if (!camera.site_from_frame) {
    throw Error(camera.source + ": the label gives no pose of " + camera.frame +
                " in a SITE_FRAME; expected a ROVER_COORDINATE_SYSTEM group");
  }
  return cahvor->Transformed(*camera.site_from_frame);
}

SiteStereo RunSiteStereo(const MissionRunContext& run, const MissionSite& site,
                         const ProgressCallback& progress) {
  SiteStereo result;
  result.cloud.site = site.site;
  result.cloud.frame = "SITE_FRAME site " + std::to_string(site.site);
  Eigen::Vector3d centre_sum = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < site.pairs.size(); ++i) {
    const MissionStereoPair& pair = site.pairs[i];
    if (progress &&
        !progress(static_cast<double>(i) / static_cast<double>(site.pairs.size()), "stereo")) {
      throw Error("cancelled during stereo of " + SiteName(site.site));
    }
    const CameraFile left = ReadCameraFile(pair.left_label);
    const CameraFile right = ReadCameraFile(pair.right_label);
    const cv::Mat left_image = ReadImage(pair.left_image);
    const cv::Mat right_image = ReadImage(pair.right_image);
    DenseStereoOptions stereo = run.options->stereo;
    stereo.image_id = static_cast<uint16_t>(i);
    const DenseStereoResult dense = RunDenseStereo(left_image, right_image, left, right, stereo);
    const double spacing_m = run.options->PointSpacingFor(dense.summary.focal_px);
    const PointCloud thinned = ThinToGroundSpacing(dense.cloud, spacing_m, dense.summary.focal_px);
    result.cloud.points.insert(result.cloud.points.end(), thinned.points.begin(),
                               thinned.points.end());
    centre_sum += dense.cloud.camera_center;
    result.images.push_back({static_cast<int>(i), left_image, CameraInSite(left)});
    result.pairs.push_back({pair.instrument, pair.pair, static_cast<int>(i),
                            static_cast<int64_t>(dense.summary.points),
                            static_cast<int64_t>(dense.summary.line_of_sight.buried),
                            static_cast<int64_t>(dense.summary.line_of_sight.floating),
                            static_cast<int64_t>(thinned.points.size()), spacing_m,
                            dense.summary.valid_fraction});
  }
  if (!site.pairs.empty()) centre_sum /= static_cast<double>(site.pairs.size());
  result.cloud.camera_center = centre_sum;
  if (run.options->prefer_precise_pairs) {
    const size_t before = result.cloud.points.size();
    result.cloud = KeepMostPreciseSource(result.cloud, run.options->precise_pairs);
    result.coarse_points_dropped = before - result.cloud.points.size();
  }
  return result;
}

}  // namespace

SiteRegistrationResult RegisterSiteOrtho(const MissionRunContext& run, const Orthophoto& ortho,
                                         const fs::path& ortho_path, int site,
                                         const OrbitalPrior& prior,
                                         const OrbitalMatchOptions& options, const fs::path& dir) {
  const MissionOrbitalProduct* image = run.mission->FirstOrbital("image");
  if (image == nullptr) {
    SiteRegistrationResult skipped;
    skipped.skipped = true;
    skipped.reason = "the mission has no orbital image";
    return skipped;
  }
  std::optional<OrbitalImage> orbital_dtm;
  if (const MissionOrbitalProduct* dtm = run.mission->FirstOrbital("dtm")) {
    orbital_dtm = OrbitalImage::Open(dtm->path);
  }
  OrthoRegistrationOptions job;
  job.verify_edges = false;
  job.match = options;
  job.control = run.options->control;
  const OrthoRegistration registration =
      RegisterOrthoImage(OrthoImageFromOrthophoto(ortho, ortho_path.string(), site, prior.position),
                         {OrbitalImage::Open(image->path)}, orbital_dtm, prior, job);
  const OrbitalMatch& match = registration.result.matches.front();
  if (const cv::Mat surface = CorrelationSurfaceImage(match); !surface.empty()) {
    WriteImage(dir / "correlation_surface.png", surface);
  }
  std::vector<ControlPoint> controls;
  for (const OrbitalControlPoint& point : registration.control_points) {
    ControlPoint control = point.point;
    control.id = "site" + std::to_string(site) + "-" + control.id;  // Unique in the run.
    controls.push_back(control);
  }
  WriteFileAtomically(dir / "control_points.json",
                      json{{"control_points", ControlPointsToJson(controls)}}.dump(2));
  // registration.json is the match's record (MatchJson); the result is that record read back, as
  // a later run (a leg's prior, a resumed unit) reads the file.
  json report = MatchJson(match);
  report["prior_sigma_m"] = prior.sigma_m;
  report["control_points"] = controls.size();
  WriteFileAtomically(dir / "registration.json", report.dump(2));
  return SiteRegistrationResult::FromJson(report, (dir / "registration.json").string());
}

std::vector<OrthoSourceImage> SiteOrthoImages(const MissionSite& site, int first_id) {
  std::vector<OrthoSourceImage> images;
  for (const MissionStereoPair& pair : site.pairs) {
    images.push_back({first_id + static_cast<int>(images.size()), ReadImage(pair.left_image),
                      CameraInSite(ReadCameraFile(pair.left_label))});
  }
  return images;
}

SiteUnitResult RegisterSite(const MissionRunContext& run, size_t site_index,
                            const ProgressCallback& progress) {
  const MissionSite& site = run.mission->sites.at(site_index);
  const fs::path dir = SiteDir(run, site.site);
  fs::create_directories(dir);
  const Rigid3d traverse_from_site = TelemetryTraverseFromSite(run.mission->telemetry[site_index]);
  const SiteGeoreference georef =
      SiteGeoreference::InMission(run.mission->body, run.mission->origin, traverse_from_site);

  const auto stage = [&](double from, double to) -> ProgressCallback {
    if (!progress) return nullptr;
    return [=](double f, std::string_view name) { return progress(from + (to - from) * f, name); };
  };
  SiteUnitResult result;
  result.site = site.site;
  auto clock = std::chrono::steady_clock::now();
  SiteStereo stereo = RunSiteStereo(run, site, stage(0.0, 0.5));
  if (stereo.cloud.points.empty()) {
    throw Error(SiteName(site.site) + ": stereo gave no 3D points in " +
                std::to_string(site.pairs.size()) + " pairs; check the images and labels");
  }
  WritePointCloudPly(stereo.cloud, dir / "points.ply");
  result.seconds["stereo"] = SecondsSince(clock);
  clock = std::chrono::steady_clock::now();

  const Dtm dtm =
      MakeDtm({SiteCloud{&stereo.cloud, georef}}, run.map, run.options->dtm, stage(0.5, 0.6));
  WriteDtm(dir / "dtm.tif", dtm);
  result.seconds["dtm"] = SecondsSince(clock);
  clock = std::chrono::steady_clock::now();
  const Orthophoto ortho =
      MakeOrthophoto(dtm, georef, run.map, stereo.images, run.options->ortho, stage(0.6, 0.8));
  WriteOrthophoto(dir / "ortho.tif", ortho);
  result.seconds["ortho"] = SecondsSince(clock);
  clock = std::chrono::steady_clock::now();

  const double prior_sigma =
      run.options->prior_sigma_floor_m +
      run.options->prior_sigma_per_m * DrivenDistance(*run.mission, site_index);
  const OrbitalPrior prior{georef.Origin(), georef.body, prior_sigma};
  result.registration =
      RegisterSiteOrtho(run, ortho, dir / "ortho.tif", site.site, prior, run.options->match, dir);
  result.seconds["registration"] = SecondsSince(clock);
  if (progress) progress(1.0, "registration");

  const double cell_area = dtm.layers.grid.posting * dtm.layers.grid.posting;
  result.pairs = std::move(stereo.pairs);
  result.points = static_cast<int64_t>(stereo.cloud.points.size());
  result.coarse_points_dropped = static_cast<int64_t>(stereo.coarse_points_dropped);
  result.dtm_known_area_m2 = dtm.layers.known_cells * cell_area;
  result.ortho_valid_area_m2 = ortho.valid_cells * cell_area;
  return result;
}

}  // namespace areomap::mission_run
