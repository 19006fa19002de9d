#include "areomap/map/raster.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <cpl_string.h>
#include <gdal_priv.h>
#include <opencv2/imgproc.hpp>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "gdal_util.h"

namespace areomap {
namespace {

struct GdalTypeMapping {
  GDALDataType gdal;
  int cv_depth;
};

GdalTypeMapping MappingForGdal(GDALDataType type, const std::filesystem::path& path) {
  switch (type) {
    case GDT_Byte:
      return {GDT_Byte, CV_8U};
    case GDT_UInt16:
      return {GDT_UInt16, CV_16U};
    case GDT_Int16:
      return {GDT_Int16, CV_16S};
    case GDT_Int32:
      return {GDT_Int32, CV_32S};
    case GDT_Float32:
      return {GDT_Float32, CV_32F};
    case GDT_Float64:
      return {GDT_Float64, CV_64F};
    case GDT_UInt32:  // No unsigned 32-bit cv::Mat: widen.
      return {GDT_Float64, CV_64F};
    default:
      throw Error(path.string() + ": band type " + GDALGetDataTypeName(type) +
                  " is not supported: expected an integer or real type");
  }
}

// Whether every value of the GDAL type is a float exactly (integers of up to 16 bits, Float32).
bool ValuesExactInFloat(GDALDataType type) {
  return type == GDT_Byte || type == GDT_UInt16 || type == GDT_Int16 || type == GDT_Float32;
}

GDALDataType GdalTypeForCvDepth(int depth, const std::filesystem::path& path) {
  switch (depth) {
    case CV_8U:
      return GDT_Byte;
    case CV_16U:
      return GDT_UInt16;
    case CV_16S:
      return GDT_Int16;
    case CV_32S:
      return GDT_Int32;
    case CV_32F:
      return GDT_Float32;
    case CV_64F:
      return GDT_Float64;
    default:
      throw Error(path.string() + ": cannot write pixel depth " + std::to_string(depth) +
                  ": expected 8U, 16U, 16S, 32S, 32F or 64F");
  }
}

struct GdalDatasetCloser {
  void operator()(GDALDataset* dataset) const { GDALClose(dataset); }
};
using GdalDatasetPtr = std::unique_ptr<GDALDataset, GdalDatasetCloser>;

// A read-only GDAL handle on `path`; throws areomap::Error naming the file where there is none.
GdalDatasetPtr OpenHandle(const std::filesystem::path& path) {
  internal::EnsureGdalInitialized();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    throw Error(path.string() + ": no such file");
  }
  if (std::filesystem::is_directory(path, ec)) {
    throw Error(path.string() + ": is a folder: expected a raster file");
  }
  internal::QuietGdalErrors quiet;
  GdalDatasetPtr dataset(GDALDataset::Open(path.c_str(), GDAL_OF_RASTER | GDAL_OF_READONLY));
  if (dataset == nullptr) {
    throw Error(path.string() +
                ": not a readable raster (expected GeoTIFF, PDS3/PDS4, ISIS3 "
                "cube, VICAR, JPEG 2000, PNG or another GDAL format): " +
                internal::LastGdalError());
  }
  return dataset;
}

}  // namespace

GeoTransform GeoTransform::NorthUp(double x_left, double y_top, double pixel_size_x,
                                   double pixel_size_y) {
  return GeoTransform{{x_left, pixel_size_x, 0.0, y_top, 0.0, -pixel_size_y}};
}

Eigen::Vector2d GeoTransform::PixelToMap(double col, double row) const {
  return {c[0] + col * c[1] + row * c[2], c[3] + col * c[4] + row * c[5]};
}

Eigen::Vector2d GeoTransform::MapToPixel(double x, double y) const {
  const double det = c[1] * c[5] - c[2] * c[4];
  if (det == 0.0 || !std::isfinite(det)) {
    return {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN()};
  }
  const double dx = x - c[0];
  const double dy = y - c[3];
  return {(c[5] * dx - c[2] * dy) / det, (-c[4] * dx + c[1] * dy) / det};
}

struct RasterDataset::Impl {
  GdalDatasetPtr dataset;
};

RasterDataset::RasterDataset(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
RasterDataset::~RasterDataset() = default;
RasterDataset::RasterDataset(RasterDataset&&) noexcept = default;
RasterDataset& RasterDataset::operator=(RasterDataset&&) noexcept = default;

RasterDataset RasterDataset::Reopen() const {
  // The file was checked and described by Open: only the handle is new.
  auto impl = std::make_unique<Impl>();
  impl->dataset = OpenHandle(info_.path);
  RasterDataset out(std::move(impl));
  out.info_ = info_;
  return out;
}

RasterDataset RasterDataset::Open(const std::filesystem::path& path) {
  GdalDatasetPtr dataset = OpenHandle(path);
  internal::QuietGdalErrors quiet;
  if (dataset->GetRasterCount() < 1) {
    throw Error(path.string() + ": has no raster bands: expected an image");
  }
  // A truncated file usually opens (headers come first) but its last block is missing: read the
  // last pixel of the last band (one block) so the failure shows here, naming the file.
  {
    GDALRasterBand* last = dataset->GetRasterBand(dataset->GetRasterCount());
    double probe = 0.0;
    if (last->RasterIO(GF_Read, dataset->GetRasterXSize() - 1, dataset->GetRasterYSize() - 1, 1, 1,
                       &probe, 1, 1, GDT_Float64, 0, 0, nullptr) != CE_None) {
      throw Error(path.string() +
                  ": truncated or corrupt raster (its last block cannot be "
                  "read): " +
                  internal::LastGdalError());
    }
  }
  RasterInfo info;
  info.path = path;
  info.driver = dataset->GetDriver() != nullptr ? dataset->GetDriver()->GetDescription() : "";
  info.width = dataset->GetRasterXSize();
  info.height = dataset->GetRasterYSize();
  info.band_count = dataset->GetRasterCount();
  GDALRasterBand* band = dataset->GetRasterBand(1);
  info.data_type = GDALGetDataTypeName(band->GetRasterDataType());
  int has_value = 0;
  const double nodata = band->GetNoDataValue(&has_value);
  if (has_value) info.nodata = nodata;
  info.scale = band->GetScale(&has_value);
  if (!has_value) info.scale = 1.0;
  info.offset = band->GetOffset(&has_value);
  if (!has_value) info.offset = 0.0;
  GeoTransform geotransform;
  if (dataset->GetGeoTransform(geotransform.c.data()) == CE_None) {
    info.geotransform = geotransform;
  }
  if (const OGRSpatialReference* srs = dataset->GetSpatialRef(); srs != nullptr) {
    char* wkt = nullptr;
    const char* options[] = {"FORMAT=WKT2_2019", nullptr};
    if (srs->exportToWkt(&wkt, options) == OGRERR_NONE && wkt != nullptr) info.crs_wkt = wkt;
    CPLFree(wkt);
  }
  for (int b = 1; b <= info.band_count; ++b) {
    const char* description = dataset->GetRasterBand(b)->GetDescription();
    info.band_descriptions.emplace_back(description != nullptr ? description : "");
  }
  if (char** domains = dataset->GetMetadataDomainList(); domains != nullptr) {
    for (char** d = domains; *d != nullptr; ++d) info.metadata_domains.emplace_back(*d);
    CSLDestroy(domains);
  }
  auto impl = std::make_unique<Impl>();
  impl->dataset = std::move(dataset);
  RasterDataset out(std::move(impl));
  out.info_ = std::move(info);
  return out;
}

cv::Mat RasterDataset::ReadWindow(int band, const PixelWindow& window) const {
  cv::Mat out;
  Read(band, window, false, &out);
  return out;
}

void RasterDataset::Read(int band_index, const PixelWindow& w, bool float_if_exact,
                         cv::Mat* out) const {
  if (band_index < 1 || band_index > info_.band_count) {
    throw Error(info_.path.string() + ": band " + std::to_string(band_index) +
                " does not exist: expected 1.." + std::to_string(info_.band_count));
  }
  if (w.width <= 0 || w.height <= 0 || w.col0 < 0 || w.row0 < 0 || w.col0 + w.width > info_.width ||
      w.row0 + w.height > info_.height) {
    throw Error(info_.path.string() + ": window col " + std::to_string(w.col0) + " row " +
                std::to_string(w.row0) + " size " + std::to_string(w.width) + "x" +
                std::to_string(w.height) + " is outside the raster (" +
                std::to_string(info_.width) + "x" + std::to_string(info_.height) + ")");
  }
  GDALRasterBand* band = impl_->dataset->GetRasterBand(band_index);
  const GDALDataType stored = band->GetRasterDataType();
  const GdalTypeMapping mapping = float_if_exact && ValuesExactInFloat(stored)
                                      ? GdalTypeMapping{GDT_Float32, CV_32F}
                                      : MappingForGdal(stored, info_.path);
  out->create(w.height, w.width, CV_MAKETYPE(mapping.cv_depth, 1));
  internal::QuietGdalErrors quiet;
  const CPLErr err =
      band->RasterIO(GF_Read, w.col0, w.row0, w.width, w.height, out->data, w.width, w.height,
                     mapping.gdal, 0, static_cast<GSpacing>(out->step[0]), nullptr);
  if (err != CE_None) {
    throw Error(info_.path.string() +
                ": read failed (truncated or corrupt file?): " + internal::LastGdalError());
  }
}

cv::Mat RasterDataset::ReadWindowFloat(int band, const PixelWindow& window) const {
  cv::Mat out;
  ReadWindowFloatInto(band, window, &out);
  return out;
}

void RasterDataset::ReadWindowFloatInto(int band, const PixelWindow& window, cv::Mat* out) const {
  RequireOption(out != nullptr, "ReadWindowFloatInto.out", "a matrix to read into");
  const auto nodata = info_.nodata;
  const bool unscaled = info_.scale == 1.0 && info_.offset == 0.0;
  // Unscaled integers of up to 16 bits come as floats, exactly: so are their comparisons with a
  // nodata value below (a nodata value that is not such a float matches none of them). Float
  // pixels are converted in place, other types row by row through one double row (a
  // whole-window double copy costs twice the window's float size).
  Read(band, window, unscaled, out);
  const cv::Mat stored = *out;
  if (stored.depth() != CV_32F) {
    out->release();  // `stored` keeps the pixels
    out->create(stored.size(), CV_32F);
  }
  if (stored.depth() == CV_32F && unscaled) {
    // Floats without scaling: the same as below (1 x v + 0 rounds back to v), without the
    // doubles. A nodata value that is not a float never equals one of them.
    const bool nodata_in_range = nodata && std::abs(*nodata) <= std::numeric_limits<float>::max();
    const float nodata_value = nodata_in_range ? static_cast<float>(*nodata) : 0.0f;
    const bool nodata_is_float = nodata_in_range && static_cast<double>(nodata_value) == *nodata;
    // Branch-free, so that the compiler vectorises it; without a float nodata value the
    // comparison is with a NaN, never true.
    const float nodata_match =
        nodata_is_float ? nodata_value : std::numeric_limits<float>::quiet_NaN();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int r = 0; r < out->rows; ++r) {
      float* v = out->ptr<float>(r);
      for (int c = 0; c < out->cols; ++c) {
        const float x = v[c];
        const bool finite = std::abs(x) <= std::numeric_limits<float>::max();
        v[c] = finite && x != nodata_match ? x : nan;
      }
    }
    return;
  }
  cv::Mat row(1, stored.cols, CV_64F);
  for (int r = 0; r < stored.rows; ++r) {
    stored.row(r).convertTo(row, CV_64F);  // a copy: *out may share the pixels of `stored`
    const double* in = row.ptr<double>(0);
    float* dst = out->ptr<float>(r);
    for (int c = 0; c < stored.cols; ++c) {
      const bool missing = !std::isfinite(in[c]) || (nodata && in[c] == *nodata);
      dst[c] = missing ? std::numeric_limits<float>::quiet_NaN()
                       : static_cast<float>(info_.scale * in[c] + info_.offset);
    }
  }
}

std::optional<nlohmann::json> RasterDataset::LabelJson(const std::string& domain) const {
  char** metadata = impl_->dataset->GetMetadata(domain.c_str());
  if (metadata == nullptr || metadata[0] == nullptr) return std::nullopt;
  const nlohmann::json parsed = nlohmann::json::parse(metadata[0], nullptr, false);
  if (parsed.is_discarded()) {
    throw Error(info_.path.string() + ": label in metadata domain " + domain +
                " is not valid JSON");
  }
  return parsed;
}

void WriteGeoTiff(const std::filesystem::path& path, const GeoRaster& raster,
                  const GeoTiffOptions& options) {
  if (raster.bands.empty()) throw Error(path.string() + ": nothing to write: no bands");
  const cv::Mat& first = raster.bands.front();
  for (const cv::Mat& band : raster.bands) {
    if (band.size() != first.size() || band.type() != first.type() || band.channels() != 1) {
      throw Error(path.string() +
                  ": bands differ in size or type: expected single-channel "
                  "bands of one size and type");
    }
  }
  if (first.empty()) throw Error(path.string() + ": nothing to write: empty band");
  if (options.tile_size <= 0 || options.tile_size % 16 != 0) {
    throw Error("GeoTiffOptions.tile_size " + std::to_string(options.tile_size) +
                " is invalid: expected a positive multiple of 16");
  }
  const GDALDataType type = GdalTypeForCvDepth(first.depth(), path);
  internal::EnsureGdalInitialized();
  AtomicFile file(path);
  {
    internal::QuietGdalErrors quiet;
    GDALDriver* driver = GetGDALDriverManager()->GetDriverByName("GTiff");
    const std::string tile = std::to_string(options.tile_size);
    CPLStringList create_options;
    create_options.SetNameValue("TILED", "YES");
    create_options.SetNameValue("BLOCKXSIZE", tile.c_str());
    create_options.SetNameValue("BLOCKYSIZE", tile.c_str());
    create_options.SetNameValue("COMPRESS", options.compression.c_str());
    if (type == GDT_Float32 || type == GDT_Float64) {
      create_options.SetNameValue("PREDICTOR", "3");
    } else {
      create_options.SetNameValue("PREDICTOR", "2");
    }
    create_options.SetNameValue("BIGTIFF", "IF_SAFER");
    GdalDatasetPtr dataset(driver->Create(file.temp_path().c_str(), first.cols, first.rows,
                                          static_cast<int>(raster.bands.size()), type,
                                          create_options.List()));
    if (dataset == nullptr) {
      throw Error(path.string() + ": cannot create GeoTIFF: " + internal::LastGdalError());
    }
    dataset->SetGeoTransform(const_cast<double*>(raster.geotransform.c.data()));
    if (!raster.crs_wkt.empty()) {
      OGRSpatialReference srs;
      if (srs.SetFromUserInput(raster.crs_wkt.c_str()) != OGRERR_NONE) {
        throw Error(path.string() + ": CRS to write is not valid: " + internal::LastGdalError());
      }
      dataset->SetSpatialRef(&srs);
    }
    for (size_t i = 0; i < raster.bands.size(); ++i) {
      GDALRasterBand* band = dataset->GetRasterBand(static_cast<int>(i) + 1);
      if (raster.nodata) band->SetNoDataValue(*raster.nodata);
      if (i < raster.band_names.size()) band->SetDescription(raster.band_names[i].c_str());
      const cv::Mat& data = raster.bands[i];
      if (band->RasterIO(GF_Write, 0, 0, data.cols, data.rows, const_cast<uchar*>(data.data),
                         data.cols, data.rows, type, 0, static_cast<GSpacing>(data.step[0]),
                         nullptr) != CE_None) {
        throw Error(path.string() + ": write failed: " + internal::LastGdalError());
      }
    }
    dataset->FlushCache();
    CPLErrorReset();
    dataset.reset();  // Closing writes the remaining tiles.
    if (CPLGetLastErrorType() == CE_Failure) {
      throw Error(path.string() + ": closing GeoTIFF failed: " + internal::LastGdalError());
    }
  }
  file.Commit();
}

int DecimationFactor(int width, int height, int max_side) {
  int factor = 1;
  while (std::max(width, height) / factor > max_side &&
         std::min(width, height) / (2 * factor) >= 1) {
    factor *= 2;
  }
  return factor;
}

cv::Mat ReadDecimated(const RasterDataset& dataset, const PixelWindow& window, int factor,
                      int64_t* valid_pixels) {
  RequireOption(factor >= 1, "ReadDecimated.factor", ">= 1");
  const int out_w = window.width / factor, out_h = window.height / factor;
  cv::Mat out(std::max(out_h, 0), std::max(out_w, 0), CV_32F);
  if (valid_pixels != nullptr) *valid_pixels = 0;
  if (out_w == 0 || out_h == 0) return out;
  const int strip_rows = std::max(1, 512 / factor);  // output rows per strip
  for (int row = 0; row < out_h; row += strip_rows) {
    const int rows = std::min(strip_rows, out_h - row);
    const PixelWindow strip{window.col0, window.row0 + row * factor, out_w * factor, rows * factor};
    const cv::Mat full = dataset.ReadWindowFloat(1, strip);
    if (valid_pixels != nullptr) *valid_pixels += cv::countNonZero(full == full);  // NaN != NaN
    cv::Mat small;
    if (factor == 1) {
      small = full;
    } else {
      cv::resize(full, small, cv::Size(out_w, rows), 0, 0, cv::INTER_AREA);
    }
    small.copyTo(out.rowRange(row, row + rows));
  }
  return out;
}

}  // namespace areomap
