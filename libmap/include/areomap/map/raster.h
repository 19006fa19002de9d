// Georeferenced rasters: reading any GDAL raster by windows, writing tiled GeoTIFF.
//
// Pixel convention (GDAL): pixel (col, row) covers [col, col+1) x [row, row+1) in pixel
// coordinates, so its centre is at (col + 0.5, row + 0.5); GeoTransform maps pixel
// coordinates to map coordinates of the raster's CRS.
//
// Failure: a file that cannot be opened or read throws areomap::Error naming the file and what
// was expected. Windows outside the raster throw too (they come from user options).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

namespace areomap {

struct GeoTransform {
  // GDAL order: x = c[0] + col c[1] + row c[2]; y = c[3] + col c[4] + row c[5].
  std::array<double, 6> c{0.0, 1.0, 0.0, 0.0, 0.0, 1.0};

  static GeoTransform NorthUp(double x_left, double y_top, double pixel_size_x,
                              double pixel_size_y);
  Eigen::Vector2d PixelToMap(double col, double row) const;
  // Returns NaNs if the transform is singular.
  Eigen::Vector2d MapToPixel(double x, double y) const;
};

// A rectangle of pixels: [col0, col0 + width) x [row0, row0 + height).
struct PixelWindow {
  int col0 = 0;
  int row0 = 0;
  int width = 0;
  int height = 0;
};

struct RasterInfo {
  std::filesystem::path path;
  std::string driver;  // GDAL short name, e.g. "GTiff", "ISIS3", "PDS".
  int width = 0;
  int height = 0;
  int band_count = 0;
  std::string data_type;  // GDAL name of band 1's type, e.g. "Float32".
  std::optional<double> nodata;
  double scale = 1.0;  // physical = scale * stored + offset
  double offset = 0.0;
  std::optional<GeoTransform> geotransform;  // None for plain images.
  std::string crs_wkt;                       // Empty when the raster has no CRS.
  std::vector<std::string> metadata_domains;
  std::vector<std::string> band_descriptions;  // One per band; empty strings where none is set.
};

class RasterDataset {
 public:
  // Opens read-only. Throws areomap::Error("<path>: ...") for a missing file, an unreadable or
  // truncated one, or a file that is not a raster.
  static RasterDataset Open(const std::filesystem::path& path);
  // A second, independent handle on the same file, with the same info() (not checked and
  // described again). A handle is not thread-safe: threads that read at once each use their own
  // (each also keeps its own GDAL block cache). Throws as Open, e.g. when the file has gone since.
  RasterDataset Reopen() const;
  ~RasterDataset();
  RasterDataset(RasterDataset&&) noexcept;
  RasterDataset& operator=(RasterDataset&&) noexcept;

  const RasterInfo& info() const { return info_; }
  PixelWindow FullWindow() const { return {0, 0, info_.width, info_.height}; }

  // Reads one band (1-based) in its stored type (CV_8U, 16U, 16S, 32S, 32F or 64F).
  cv::Mat ReadWindow(int band, const PixelWindow& window) const;
  // Reads one band as CV_32F with scale/offset applied and nodata (or non-finite) as NaN.
  cv::Mat ReadWindowFloat(int band, const PixelWindow& window) const;
  // The same into *out (not null). Bands read as floats (Float32, and Byte/UInt16/Int16 without
  // scale and offset) land in *out's memory when it already is a window-sized CV_32F matrix
  // (cv::Mat::create): a caller reading many windows passes a header over memory it reuses,
  // instead of page-faulting a fresh buffer in for every window. Other bands, or an *out of
  // another size or type, leave that memory untouched and point *out at a new matrix. Throws as
  // ReadWindowFloat.
  void ReadWindowFloatInto(int band, const PixelWindow& window, cv::Mat* out) const;
  // The product label as JSON from metadata domain `domain` (e.g. "json:PDS", "json:VICAR",
  // "json:ISIS3"); std::nullopt if the file has none.
  std::optional<nlohmann::json> LabelJson(const std::string& domain) const;

 private:
  struct Impl;
  explicit RasterDataset(std::unique_ptr<Impl> impl);
  // ReadWindow into *out (cv::Mat::create); with `float_if_exact`, a band whose every value is a
  // float exactly (integers of up to 16 bits) comes back as CV_32F, converted by GDAL while it
  // copies the blocks.
  void Read(int band, const PixelWindow& window, bool float_if_exact, cv::Mat* out) const;
  std::unique_ptr<Impl> impl_;
  RasterInfo info_;
};

// An in-memory georeferenced raster: one cv::Mat per band, all the same size and type.
struct GeoRaster {
  std::vector<cv::Mat> bands;
  GeoTransform geotransform;
  std::string crs_wkt;
  std::optional<double> nodata;
  std::vector<std::string> band_names;  // Optional band descriptions.
};

struct GeoTiffOptions {
  int tile_size = 256;                  // Tile edge [px], a multiple of 16.
  std::string compression = "DEFLATE";  // GDAL COMPRESS= value.
};

// Writes a tiled, compressed GeoTIFF atomically. Throws areomap::Error on inconsistent bands,
// an unsupported type or an unwritable destination; nothing is left behind on failure.
void WriteGeoTiff(const std::filesystem::path& path, const GeoRaster& raster,
                  const GeoTiffOptions& options = {});

// The power of two by which a width x height raster is decimated for an overview whose longer side
// is at most `max_side` px (>= 1); never so far that the shorter side falls below 1 px.
int DecimationFactor(int width, int height, int max_side);

// `window` of band 1 averaged over factor x factor blocks (factor >= 1), read in strips so that
// memory stays at the output plus one strip. Output size: window size / factor (rounded down);
// NaN where any input pixel of a block is nodata. `valid_pixels`, when given, receives the number
// of the pixels read that are valid (finite, not nodata); pixels beyond the last whole block of
// a row or column are not read.
cv::Mat ReadDecimated(const RasterDataset& dataset, const PixelWindow& window, int factor,
                      int64_t* valid_pixels = nullptr);

}  // namespace areomap
