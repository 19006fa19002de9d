#include "areomap/registration/ortho_registration.h"

#include <cmath>
#include <cstdio>
#include <string>
#include <utility>

#include "areomap/map/error.h"
#include "areomap/map/raster.h"
#include "areomap/registration/orbital_grid.h"

namespace areomap {
namespace {

// The centre of the whole orthophoto file in pixels of `ortho` (ReadOrthoImage keeps only the
// window of its valid pixels): the default prior stays the file's centre, read from its metadata.
Eigen::Vector2d FileCentreInOrtho(const std::filesystem::path& path, const OrthoImage& ortho) {
  const RasterInfo info = RasterDataset::Open(path).info();
  const Eigen::Vector2d centre =
      info.geotransform.value().PixelToMap(info.width / 2.0, info.height / 2.0);
  return ortho.geotransform.MapToPixel(centre.x(), centre.y());
}

}  // namespace

void OrthoRegistrationOptions::Check() const {
  RequireOption(std::isfinite(prior_height_m), "OrthoRegistrationOptions.prior_height_m",
                "a finite number");
  RequireOption(std::isfinite(prior_sigma_m) && prior_sigma_m > 0.0,
                "OrthoRegistrationOptions.prior_sigma_m", "a finite number > 0");
  RequireOption(!prior_position || IsValid(*prior_position),
                "OrthoRegistrationOptions.prior_position",
                "finite, latitude within [-90, 90] degrees");
  RequireOption(!site || *site >= 0, "OrthoRegistrationOptions.site", ">= 0");
  match.Check();
  control.Check();
}

OrthoRegistration RegisterOrtho(const std::filesystem::path& ortho_path,
                                const std::vector<std::filesystem::path>& orbital_paths,
                                const std::optional<std::filesystem::path>& orbital_dtm,
                                const OrthoRegistrationOptions& options,
                                const ProgressCallback& progress) {
  options.Check();
  OrthoImage ortho = ReadOrthoImage(ortho_path);
  OrbitalPrior prior;
  prior.sigma_m = options.prior_sigma_m;
  if (options.prior_position) {
    prior.position = *options.prior_position;
  } else {
    // Without telemetry: the orthophoto's centre as its georeference has it, the point of that
    // pixel's radial line at the given height.
    const PixelGrid ortho_grid(ortho.geotransform, ortho.crs_wkt, ortho.source);
    const auto centre = ortho_grid.PixelToGeographic(FileCentreInOrtho(ortho_path, ortho));
    if (!centre) throw Error(ortho_path.string() + ": its centre lies outside its CRS's domain");
    prior.position = GeographicFromMbf(
        prior.body, MbfOnRadialLine(prior.body, centre->lat, centre->lon, options.prior_height_m));
  }
  if (options.site) {
    ortho.site = *options.site;
    ortho.site_origin = prior.position;
  }
  std::vector<OrbitalImage> orbitals;
  for (const std::filesystem::path& path : orbital_paths) {
    orbitals.push_back(OrbitalImage::Open(path));
  }
  std::optional<OrbitalImage> dtm;
  if (orbital_dtm) dtm = OrbitalImage::Open(*orbital_dtm);
  OrthoRegistration done =
      RegisterOrthoImage(std::move(ortho), orbitals, dtm, prior, options, progress);
  bool any_overlap = false;
  for (const OrbitalMatch& m : done.result.matches) any_overlap = any_overlap || m.overlaps;
  if (!any_overlap) {
    char where[160];  // %.0f: a radius beyond int (prior_sigma_m 1e9) printed as it is
    std::snprintf(where, sizeof(where), "%.0f m around latitude %.6f, longitude %.6f deg",
                  options.match.search_sigmas * prior.sigma_m, DegFromRad(prior.position.lat),
                  DegFromRad(prior.position.lon));
    throw Error(std::string("no orbital image overlaps the search window: ") + where);
  }
  return done;
}

OrthoRegistration RegisterOrthoImage(OrthoImage ortho, const std::vector<OrbitalImage>& orbitals,
                                     const std::optional<OrbitalImage>& orbital_dtm,
                                     const OrbitalPrior& prior,
                                     const OrthoRegistrationOptions& options,
                                     const ProgressCallback& progress) {
  options.Check();
  OrthoRegistration registration;
  registration.ortho = std::move(ortho);
  registration.prior = prior;
  registration.result =
      MatchOrthoToOrbitals(registration.ortho, orbitals, prior, options.match, progress);
  const int best = registration.result.best;
  if (best >= 0) {
    const OrbitalMatch& match = registration.result.matches[best];
    const OrbitalImage& orbital = orbitals[best];
    if (options.verify_edges) {
      EdgeVerificationOptions edge_options;
      edge_options.fit_similarity = options.similarity;
      registration.edges = VerifyMatchWithEdges(match, edge_options);
    }
    registration.control_points =
        MakeControlPoints(match, registration.ortho, orbital, prior, orbital_dtm, options.control);
    registration.corrected_geotransform = CorrectedGeoTransform(match, registration.ortho, orbital);
  }
  return registration;
}

nlohmann::json EdgeVerificationJson(const EdgeVerification& edges) {
  return {{"ortho_edges", edges.ortho_edges},
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
          {"consistent", edges.consistent}};
}

nlohmann::json OrthoRegistrationJson(const OrthoRegistration& registration) {
  const OrbitalPrior& prior = registration.prior;
  nlohmann::json json = {{"prior",
                          {{"lat_deg", DegFromRad(prior.position.lat)},
                           {"lon_deg", DegFromRad(prior.position.lon)},
                           {"sigma_m", prior.sigma_m}}},
                         {"matches", nlohmann::json::array()},
                         {"matched", registration.result.best >= 0}};
  for (const OrbitalMatch& m : registration.result.matches) json["matches"].push_back(MatchJson(m));
  if (registration.result.best >= 0) {
    json["best"] = registration.result.best;
    if (registration.edges) json["edges"] = EdgeVerificationJson(*registration.edges);
  }
  return json;
}

}  // namespace areomap
