// The two kinds of georeferenced image orbital-ground registration reads: a rover orthophoto
// (values plus validity) and orbital images (HiRISE RDR, CTX, any GDAL raster with a CRS), the
// latter read by windows so an image of any size costs only the pixels a search needs.
//
// Pixel convention (GDAL, raster.h): pixel (col, row) covers [col, col+1) x [row, row+1); its
// centre is (col + 0.5, row + 0.5) in pixel coordinates.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "areomap/map/geodesy.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/raster.h"

namespace areomap {

// A rover orthophoto in memory. Invalid pixels (no stereo coverage, occlusion, the rover's own
// shadow) are NaN in `image` and/or zero in `mask`.
struct OrthoImage {
  cv::Mat image;  // CV_32FC1, any intensity unit, NaN where invalid.
  cv::Mat mask;   // CV_8UC1 of the image's size, nonzero = valid; empty = every finite pixel.
  GeoTransform geotransform;  // Pixel -> map coordinates of crs_wkt (the telemetry georeference).
  std::string crs_wkt;        // Must describe a Mars CRS.
  std::string source;         // File name or label, used in messages.
  // The MER site whose frame control points are expressed in, and that frame's origin
  // (planetocentric latitude, east longitude [rad], height above the ellipsoid [m]) as the
  // rover knows it (telemetry). Without them control points carry MBF coordinates only.
  std::optional<int> site;
  std::optional<Geographic> site_origin;

  // A mask that is nonzero exactly where the pixel is usable (finite and mask-valid). Throws
  // areomap::Error naming `source` for an image not CV_32FC1 or a mask not CV_8UC1 of its size.
  cv::Mat ValidMask() const;
};

// Reads an orthophoto GeoTIFF (any GDAL raster with a geotransform and a CRS): band 1 holds
// the values (its nodata and non-finite values are invalid); a second band, if present, is a
// validity mask (nonzero = valid). Only the smallest window holding every finite value of band 1
// is kept (ValidPixelWindow: band 1 is scanned in strips first), `geotransform` being that
// window's: memory by the valid window, not the raster. Throws areomap::Error naming the file
// for a missing or unreadable file, no georeference or no CRS, or no valid pixel at all (found
// by the scan, before any window is read); the CRS is checked to be on Mars by the matcher.
OrthoImage ReadOrthoImage(const std::filesystem::path& path);

// The orthophoto libmap makes (orthophoto.h, mosaic.h) as a matching input: its image and
// validity mask on its grid and CRS. `site`/`site_origin` as in OrthoImage (telemetry origin).
OrthoImage OrthoImageFromOrthophoto(const Orthophoto& ortho, std::string source,
                                    std::optional<int> site = std::nullopt,
                                    std::optional<Geographic> site_origin = std::nullopt);

// An orbital image (or an orbital DTM) read by windows, from a file or from memory.
class OrbitalImage {
 public:
  // Opens a georeferenced raster (band 1). Throws areomap::Error naming the file if it is
  // missing, unreadable, or has no geotransform or CRS.
  static OrbitalImage Open(const std::filesystem::path& path);
  // Wraps band 0 of an in-memory raster (e.g. a generator product). Throws areomap::Error if
  // the raster has no band or no CRS.
  static OrbitalImage FromGeoRaster(GeoRaster raster, std::string name);

  int width() const { return width_; }
  int height() const { return height_; }
  const GeoTransform& geotransform() const { return geotransform_; }
  const std::string& crs_wkt() const { return crs_wkt_; }
  const std::string& name() const { return name_; }
  // Ground sample distance: mean pixel edge in map units [m for projected CRSs].
  double PixelSize() const;

  // The pixels of `window` clipped to the image as CV_32F with scale/offset applied and
  // nodata or non-finite values as NaN; `window` is updated to the clipped rectangle (width or
  // height 0 when nothing of it lies on the image, and the Mat is then empty).
  cv::Mat ReadWindow(PixelWindow& window) const;
  // Bilinear sample of band 1 at pixel coordinates (col, row) (GDAL convention); NaN off the
  // image or next to an invalid pixel. Reads a 2x2 window: for a handful of points only.
  double SampleBilinear(double col, double row) const;

 private:
  OrbitalImage() = default;
  std::shared_ptr<const RasterDataset> dataset_;
  cv::Mat memory_;  // CV_32F with NaN, when in memory.
  GeoTransform geotransform_;
  std::string crs_wkt_;
  std::string name_;
  int width_ = 0;
  int height_ = 0;
};

}  // namespace areomap
