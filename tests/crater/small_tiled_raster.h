// A test raster whose reads decode many small compressed blocks.
#pragma once

#include <filesystem>

#include <opencv2/core.hpp>

#include "areomap/map/raster.h"

namespace areomap::testing {

// `image` (one band) written at `path` as a deflate GeoTIFF in 64 px tiles, and opened.
inline RasterDataset WriteSmallTiledRaster(const std::filesystem::path& path,
                                           const cv::Mat& image) {
  GeoRaster raster;
  raster.bands = {image};
  GeoTiffOptions tiff;
  tiff.tile_size = 64;
  WriteGeoTiff(path, raster, tiff);
  return RasterDataset::Open(path);
}

}  // namespace areomap::testing
