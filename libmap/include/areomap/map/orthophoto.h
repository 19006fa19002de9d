// Orthophotos from rover images draped on a rover DTM: for each DTM cell the best image that sees
// it is sampled (bilinear), with a source-image-id layer, a validity mask and a resolution map.
//
// Frames: the DTM is on a map (dtm.h: x, y [m] in its projected CRS, elevation = height above
// the body's ellipsoid); cameras are CAHV(OR) models in the site frame of `site` (MER SITE_FRAME,
// x north, y east, z down), e.g. a label's ROVER_FRAME model moved by its site_from_rover pose
// (CahvorModel::Transformed). Pixels follow JPL's convention (first pixel centre at (0, 0)).
//
// Visibility is a depth test against the DTM: each image gets a depth buffer of the DTM's cell
// quads (two triangles each, range from the camera), and a cell is seen by an image only if its
// own range is within the depth tolerance of the buffer's at its pixel (the DTM's sigma moves
// where a grazing ray meets the surface by sigma / cos(incidence), so the tolerance grows with
// it): occluded cells are not painted with what hides them. Among the images that see a cell the
// one with the finest ground sample is chosen: range / (focal [px] cos(incidence)), the pixel
// footprint along the slope — nearest and least oblique at once. That footprint is the resolution
// layer [m].
//
// Failure: invalid options, no images, or an empty or non-single-channel image throw
// areomap::Error naming the field or the image id. Cells no image sees are invalid (NaN image,
// 0 in the mask, -1 source).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "areomap/map/cahvor.h"
#include "areomap/map/dtm.h"
#include "areomap/map/dtm_gridding.h"
#include "areomap/map/progress.h"
#include "areomap/map/raster.h"
#include "areomap/map/site_georeference.h"

namespace areomap {

struct OrthoSourceImage {
  int id = 0;                  // Written into the source-id layer; unique across a mosaic.
  cv::Mat image;               // Single channel, any depth (DN), read as float.
  CahvorModel camera_in_site;  // The camera in the site frame.
};

struct OrthoOptions {
  double max_range_m = 30.0;  // Cells farther from the camera are not painted [m].
  // View ray vs surface normal beyond this is too oblique. Flat ground seen from a 1.5 m mast
  // is at 84 deg incidence at 15 m and 87 deg at 30 m.
  double max_incidence_deg = 88.0;
  double normal_baseline_m = 0.5;          // Surface normals from the DTM over this baseline [m].
  double depth_tolerance_m = 0.05;         // Depth test slack: absolute [m] ...
  double depth_tolerance_relative = 0.02;  // ... plus this fraction of the range ...
  double depth_tolerance_sigmas = 3.0;     // ... plus this many DTM sigmas / cos(incidence).
  void Check() const;                      // Throws areomap::Error naming the field.
};

struct Orthophoto {
  GridSpec grid;  // A window of the DTM's grid.
  std::string crs_wkt;
  cv::Mat image;       // CV_32F DN, NaN where invalid.
  cv::Mat valid;       // CV_8U, 1 where painted.
  cv::Mat resolution;  // CV_32F ground sample size [m], NaN where invalid.
  cv::Mat source_id;   // CV_32S, -1 where invalid.
  int valid_cells = 0;

  // Float32 bands "image", "valid", "resolution_m", "source_id"; nodata NaN (the mask and the
  // id stay 0 / -1 where invalid).
  GeoRaster ToGeoRaster() const;
};

// The window of `dtm_grid` within options.max_range_m of the cameras (which may stand far from
// the site's origin), or std::nullopt when the grid does not reach them: what MakeOrthophoto
// paints, so a caller can read just that window of a large DTM (ReadDtm). Throws
// areomap::Error when a camera lies outside the map's CRS domain.
std::optional<GridSpec> OrthophotoWindow(const GridSpec& dtm_grid, const SiteGeoreference& site,
                                         const MapFrame& map,
                                         const std::vector<OrthoSourceImage>& images,
                                         const OrthoOptions& options);

// The orthophoto of one site's images on the window of `dtm` within max_range_m of their
// cameras (which may stand far from the site's origin). Throws areomap::Error when the DTM does
// not reach the cameras, or for bad images or options.
Orthophoto MakeOrthophoto(const Dtm& dtm, const SiteGeoreference& site, const MapFrame& map,
                          const std::vector<OrthoSourceImage>& images, const OrthoOptions& options,
                          const ProgressCallback& progress = nullptr);

// Writes the orthophoto as a tiled, compressed GeoTIFF, atomically.
void WriteOrthophoto(const std::filesystem::path& path, const Orthophoto& ortho);

// Reads a GeoTIFF written by WriteOrthophoto. Throws areomap::Error naming the file when it does
// not have that layout (4 bands: image, valid, resolution_m, source_id) on a north-up grid.
Orthophoto ReadOrthophoto(const std::filesystem::path& path);
// The same, only the cells of `window` (a window of the file's grid): memory by the window.
Orthophoto ReadOrthophoto(const std::filesystem::path& path, const GridSpec& window);

// The smallest window of an orthophoto's grid that holds all its painted cells (band "valid"
// nonzero), found by reading that band in strips (memory by a strip, not the raster);
// std::nullopt when no cell is painted. Same layout errors as ReadOrthophoto.
std::optional<GridSpec> OrthophotoValidWindow(const std::filesystem::path& path);

}  // namespace areomap
