// A small built-in georeferenced Mars terrain: a DTM with one fresh simple crater (raised rim,
// bowl floor) on a gently rolling fractal background, map-projected like a HiRISE DTM
// (equirectangular on the local-radius sphere at the centre latitude).
//
// It is the bundled sample of the quick start until the full mission generator replaces it,
// and a fixture for raster/CRS tests. Deterministic: the same options give the same bytes.
#pragma once

#include <cstdint>

#include "areomap/map/raster.h"

namespace areomap {

struct SampleTerrainOptions {
  double center_lat_deg = -14.5692;   // Planetocentric latitude of the tile centre [deg] (Gusev).
  double center_lon_deg = 175.4729;   // East longitude of the tile centre [deg].
  int size_px = 256;                  // Tile edge [px].
  double posting_m = 1.0;             // Pixel size [m].
  double crater_diameter_m = 80.0;    // Rim-to-rim diameter [m].
  double crater_depth_m = 12.0;       // Rim crest to floor [m] (fresh: ~0.2 D).
  double rim_height_m = 3.0;          // Rim crest above the surroundings [m].
  double roughness_m = 1.5;           // RMS amplitude of the fractal background [m].
  double base_elevation_m = -1900.0;  // Mean height above the ellipsoid [m].
  uint32_t seed = 1;                  // Seed of the background's random phases.

  // Throws areomap::Error naming the first invalid field.
  void Check() const;
};

// Returns a single-band Float32 DTM (heights [m] above the IAU 2000 ellipsoid) with its
// geotransform and CRS; nodata = -3.4028227e+38 (the ISIS convention) is declared but unused.
GeoRaster MakeSampleTerrain(const SampleTerrainOptions& options);

}  // namespace areomap
