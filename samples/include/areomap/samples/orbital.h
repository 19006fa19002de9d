// Orbital products of the mission generator: a HiRISE-like orthoimage (Lambertian shading with
// cast shadows, MTF blur, noise, 10-bit quantisation) and an orbital DTM, both map-projected like
// HiRISE RDR products (equirectangular on the local-radius sphere at the site latitude).
#pragma once

#include <cstdint>

#include "areomap/map/geodesy.h"
#include "areomap/map/progress.h"
#include "areomap/map/projection.h"
#include "areomap/map/raster.h"
#include "areomap/samples/scene.h"

namespace areomap {

// Where the scene's local ENU frame sits on Mars and how its map grid is laid out.
struct SceneGeoreference {
  Body body = Body::Mars2000();
  Geographic origin;  // Planetocentric latitude, east longitude [rad] and h [m] of ENU (0, 0, 0).

  MapProjection Projection() const;  // Equirectangular, local radius at the origin latitude.
  Rigid3d EnuFromMbf() const;
};

struct OrbitalImageOptions {
  double gsd_m = 0.25;              // Ground sample distance [m] (HiRISE RDR 0.25-0.32 m).
  double sun_azimuth_deg = 120.0;   // Sun direction, clockwise from north [deg].
  double sun_elevation_deg = 30.0;  // Sun above the horizon [deg].
  double ambient = 0.12;            // Diffuse sky light as a fraction of direct light.
  int supersample = 2;              // Sub-pixels per pixel edge for rendering.
  double mtf_sigma_px = 0.5;        // Gaussian blur of the optics and detector [px].
  double read_noise_dn = 1.5;       // Gaussian noise [DN].
  double full_well_dn = 1023.0;     // DN of albedo 0.5 lit at normal incidence (saturates).
  int bits = 10;                    // Quantisation (stored in UInt16).
  uint32_t seed = 1;

  void Check() const;  // Throws areomap::Error naming the field.
};

struct OrbitalProducts {
  GeoRaster image;  // UInt16 DN, nodata none.
  GeoRaster dtm;    // Float32 heights above the ellipsoid [m] at `dtm_posting_m`.
};

// Renders the orthoimage over the square [-half_extent, half_extent]^2 around the origin and a
// DTM at `dtm_posting_m` (box-averaged from the rendering grid, like a stereo DTM's footprint).
OrbitalProducts RenderOrbitalProducts(const Scene& scene, const SceneGeoreference& georef,
                                      double half_extent_m, double dtm_posting_m,
                                      const OrbitalImageOptions& options,
                                      const ProgressCallback& progress = nullptr);

}  // namespace areomap
