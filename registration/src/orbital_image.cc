#include "areomap/registration/orbital_image.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <tbb/parallel_for.h>

#include "areomap/map/error.h"
#include "areomap/map/numbers.h"
#include "areomap/map/raster_window.h"

namespace areomap {
namespace {

void RequireGeoreference(const RasterInfo& info) {
  if (!info.geotransform) {
    throw Error(info.path.string() +
                ": has no georeference: expected a map-projected raster with a geotransform");
  }
  if (info.crs_wkt.empty()) {
    throw Error(info.path.string() + ": has no CRS: expected a Mars map projection");
  }
}

}  // namespace

cv::Mat OrthoImage::ValidMask() const {
  if (image.type() != CV_32FC1) {
    throw Error(source + ": the orthophoto image must be a CV_32FC1 band");
  }
  if (!mask.empty() && (mask.type() != CV_8UC1 || mask.size() != image.size())) {
    throw Error(source + ": the orthophoto mask must be CV_8UC1 of the image's size");
  }
  // One pass, in parallel: the template's resampling asks for it on every registration.
  cv::Mat valid(image.size(), CV_8U);
  tbb::parallel_for(0, image.rows, [&](int r) {
    const float* value = image.ptr<float>(r);
    const uchar* ok = mask.empty() ? nullptr : mask.ptr<uchar>(r);
    uchar* out = valid.ptr<uchar>(r);
    for (int c = 0; c < image.cols; ++c) {
      out[c] = std::isfinite(value[c]) && (ok == nullptr || ok[c] != 0) ? 255 : 0;
    }
  });
  return valid;
}

OrthoImage ReadOrthoImage(const std::filesystem::path& path) {
  const RasterDataset dataset = RasterDataset::Open(path);
  const RasterInfo& info = dataset.info();
  RequireGeoreference(info);
  // A pixel whose value is not finite is invalid whatever the mask says: only the window of
  // band 1's finite values is read.
  const std::optional<PixelWindow> window = ValidPixelWindow(dataset, 1, ValidCells::kFinite);
  if (!window) {
    throw Error(path.string() +
                ": band 1 has no valid pixel (every value is nodata or not finite): expected "
                "an orthophoto with image values");
  }
  OrthoImage ortho;
  ortho.image = dataset.ReadWindowFloat(1, *window);
  if (info.band_count >= 2) {
    cv::Mat mask = dataset.ReadWindow(2, *window);
    ortho.mask = mask != 0;
  }
  ortho.geotransform = WindowTransform(*info.geotransform, *window);
  ortho.crs_wkt = info.crs_wkt;
  ortho.source = path.string();
  return ortho;
}

OrbitalImage OrbitalImage::Open(const std::filesystem::path& path) {
  auto dataset = std::make_shared<const RasterDataset>(RasterDataset::Open(path));
  const RasterInfo& info = dataset->info();
  RequireGeoreference(info);
  OrbitalImage out;
  out.geotransform_ = *info.geotransform;
  out.crs_wkt_ = info.crs_wkt;
  out.name_ = path.string();
  out.width_ = info.width;
  out.height_ = info.height;
  out.dataset_ = std::move(dataset);
  return out;
}

OrbitalImage OrbitalImage::FromGeoRaster(GeoRaster raster, std::string name) {
  if (raster.bands.empty() || raster.bands[0].empty()) {
    throw Error(name + ": the raster has no band: expected one image band");
  }
  if (raster.crs_wkt.empty()) throw Error(name + ": has no CRS: expected a Mars map projection");
  OrbitalImage out;
  raster.bands[0].convertTo(out.memory_, CV_32F);
  if (raster.nodata) {
    const cv::Mat is_nodata = raster.bands[0] == *raster.nodata;
    out.memory_.setTo(std::numeric_limits<float>::quiet_NaN(), is_nodata);
  }
  out.geotransform_ = raster.geotransform;
  out.crs_wkt_ = std::move(raster.crs_wkt);
  out.name_ = std::move(name);
  out.width_ = out.memory_.cols;
  out.height_ = out.memory_.rows;
  return out;
}

double OrbitalImage::PixelSize() const {
  const auto& c = geotransform_.c;
  return 0.5 * (std::hypot(c[1], c[4]) + std::hypot(c[2], c[5]));
}

cv::Mat OrbitalImage::ReadWindow(PixelWindow& window) const {
  const int c0 = std::max(window.col0, 0), r0 = std::max(window.row0, 0);
  const int c1 = std::min(window.col0 + window.width, width_);
  const int r1 = std::min(window.row0 + window.height, height_);
  if (c1 <= c0 || r1 <= r0) {
    window = {c0, r0, 0, 0};
    return {};
  }
  window = {c0, r0, c1 - c0, r1 - r0};
  if (dataset_) return dataset_->ReadWindowFloat(1, window);
  return memory_(cv::Rect(c0, r0, c1 - c0, r1 - r0)).clone();
}

double OrbitalImage::SampleBilinear(double col, double row) const {
  if (!std::isfinite(col) || !std::isfinite(row)) return kNaN;
  // Pixel centres are at +0.5.
  const double x = col - 0.5, y = row - 0.5;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  PixelWindow window{x0, y0, 2, 2};
  const cv::Mat patch = ReadWindow(window);
  if (window.width != 2 || window.height != 2) return kNaN;
  const double fx = x - x0, fy = y - y0;
  const double v = (1 - fy) * ((1 - fx) * patch.at<float>(0, 0) + fx * patch.at<float>(0, 1)) +
                   fy * ((1 - fx) * patch.at<float>(1, 0) + fx * patch.at<float>(1, 1));
  return v;  // NaN propagates from an invalid neighbour.
}

OrthoImage OrthoImageFromOrthophoto(const Orthophoto& ortho, std::string source,
                                    std::optional<int> site,
                                    std::optional<Geographic> site_origin) {
  OrthoImage result;
  result.image = ortho.image;
  result.mask = ortho.valid;
  result.geotransform = ortho.grid.Transform();
  result.crs_wkt = ortho.crs_wkt;
  result.source = std::move(source);
  result.site = site;
  result.site_origin = site_origin;
  return result;
}

}  // namespace areomap
