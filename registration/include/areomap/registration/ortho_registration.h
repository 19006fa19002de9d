// The registration of one rover orthophoto onto orbital images as one job: the match on every
// orbital image (orbital_match.h), the edge verification of the best (edge_verify.h), its
// control points and the orthophoto's corrected georeference (orbital_report.h). What
// `areomap register` runs and the Python module's register() calls; files are the caller's.
//
// Frames and units as in orbital_match.h: the prior in planetocentric latitude, east longitude
// [rad] and height above the ellipsoid [m]; shifts in orbital pixels and metres east/north.
// Failure: throws areomap::Error for bad options (naming the field), unreadable inputs (naming
// the file), a progress callback that asks to stop, or when no orbital image reaches the search
// window; an orbital image that does not match is a result (matched = false with a reason).
#pragma once

#include <filesystem>
#include <optional>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/geodesy.h"
#include "areomap/map/progress.h"
#include "areomap/map/raster.h"
#include "areomap/registration/edge_verify.h"
#include "areomap/registration/orbital_image.h"
#include "areomap/registration/orbital_match.h"
#include "areomap/registration/orbital_report.h"

namespace areomap {

struct OrthoRegistrationOptions {
  // Where telemetry puts the rover (planetocentric latitude, east longitude [rad], height [m]);
  // nullopt: the orthophoto's centre as its georeference has it, at prior_height_m on the radial
  // line through that pixel.
  std::optional<Geographic> prior_position;
  double prior_height_m = 0.0;  // Height above the ellipsoid used without prior_position [m].
  double prior_sigma_m = 10.0;  // Horizontal 1-sigma of the prior [m], > 0.
  // MER site index: control points also in its site frame, with its origin at the prior.
  std::optional<int> site;
  bool similarity = false;  // Edge refinement fits a similarity instead of a translation.
  // Verify the best match by its edges (OrthoRegistration::edges); `areomap run` does not (its
  // sites' confidence is the match's chance level), the CLI and the Python module do.
  bool verify_edges = true;
  OrbitalMatchOptions match;
  ControlPointOptions control;

  // Throws areomap::Error naming the field and the rule it broke.
  void Check() const;
};

struct OrthoRegistration {
  OrthoImage ortho;          // As read (site and site origin set with options.site).
  OrbitalPrior prior;        // The prior searched around.
  MultiOrbitalMatch result;  // One match per orbital image, and the best.
  // Of the best match, when there is one and options.verify_edges.
  std::optional<EdgeVerification> edges;
  std::vector<OrbitalControlPoint> control_points;     // Of the best match (empty without one).
  std::optional<GeoTransform> corrected_geotransform;  // The ortho's, corrected by the best.
};

// Registers the orthophoto `ortho` (ReadOrthoImage) onto `orbitals` (OrbitalImage::Open);
// heights of control points from `orbital_dtm` where given. Progress runs over the matching.
OrthoRegistration RegisterOrtho(const std::filesystem::path& ortho,
                                const std::vector<std::filesystem::path>& orbitals,
                                const std::optional<std::filesystem::path>& orbital_dtm,
                                const OrthoRegistrationOptions& options = {},
                                const ProgressCallback& progress = nullptr);

// The same job on inputs already open: `ortho` (e.g. OrthoImageFromOrthophoto) matched on
// `orbitals` around `prior` (options' prior_* and site are not used). Unlike RegisterOrtho, an
// ortho that no orbital image overlaps is a result (every match's overlaps = false, no best).
// Throws areomap::Error for bad options, a CRS not on Mars or a progress callback that asks to
// stop. What `areomap run` runs for each site.
OrthoRegistration RegisterOrthoImage(OrthoImage ortho, const std::vector<OrbitalImage>& orbitals,
                                     const std::optional<OrbitalImage>& orbital_dtm,
                                     const OrbitalPrior& prior,
                                     const OrthoRegistrationOptions& options = {},
                                     const ProgressCallback& progress = nullptr);

// The edge verification as JSON (Table 3.7 counts and rates, the residual fit, the verdict).
nlohmann::json EdgeVerificationJson(const EdgeVerification& edges);

// The registration as JSON: "prior" (lat_deg, lon_deg, sigma_m), "matches" (MatchJson each),
// "matched", and with a match "best" (its index) and "edges" (EdgeVerificationJson).
nlohmann::json OrthoRegistrationJson(const OrthoRegistration& registration);

}  // namespace areomap
