// Rasters of any GDAL format read by windows into NumPy arrays, with their georeference.
#include <optional>
#include <string>
#include <vector>

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "areomap/map/raster.h"
#include "bindings.h"
#include "convert.h"

namespace areomap::python {
namespace {

PixelWindow WindowOf(const RasterDataset& dataset, const std::optional<std::vector<int>>& window) {
  if (!window) return dataset.FullWindow();
  if (window->size() != 4) {
    throw Error("window: expected (col0, row0, width, height) [px], got " +
                std::to_string(window->size()) + " numbers");
  }
  return {(*window)[0], (*window)[1], (*window)[2], (*window)[3]};
}

std::optional<std::vector<double>> GeoTransformList(const std::optional<GeoTransform>& t) {
  if (!t) return std::nullopt;
  return std::vector<double>(t->c.begin(), t->c.end());
}

}  // namespace

void BindRaster(py::module_& m) {
  py::class_<RasterDataset>(
      m, "Raster",
      "A raster of any format GDAL reads (GeoTIFF, ISIS3, PDS, PNG...), opened read-only and "
      "read by windows. Pixel convention (GDAL): pixel (col, row) covers [col, col+1) x "
      "[row, row+1); the geotransform maps pixel coordinates to map coordinates of the CRS "
      "(x = c0 + col c1 + row c2, y = c3 + col c4 + row c5).")
      .def(py::init([](const std::filesystem::path& path) {
             return WithoutGil([&] { return RasterDataset::Open(path); });
           }),
           py::arg("path"),
           "Opens `path`; raises areomap.Error naming it when it is missing, unreadable or not "
           "a raster.")
      .def_property_readonly("width", [](const RasterDataset& r) { return r.info().width; })
      .def_property_readonly("height", [](const RasterDataset& r) { return r.info().height; })
      .def_property_readonly("band_count",
                             [](const RasterDataset& r) { return r.info().band_count; })
      .def_property_readonly(
          "data_type", [](const RasterDataset& r) { return r.info().data_type; },
          "GDAL name of band 1's type, e.g. 'Float32'.")
      .def_property_readonly("driver", [](const RasterDataset& r) { return r.info().driver; })
      .def_property_readonly("nodata", [](const RasterDataset& r) { return r.info().nodata; })
      .def_property_readonly(
          "scale", [](const RasterDataset& r) { return r.info().scale; },
          "physical = scale x stored + offset")
      .def_property_readonly("offset", [](const RasterDataset& r) { return r.info().offset; })
      .def_property_readonly(
          "geotransform",
          [](const RasterDataset& r) { return GeoTransformList(r.info().geotransform); },
          "GDAL geotransform (c0..c5) of the whole raster, or None for a plain image.")
      .def_property_readonly(
          "crs_wkt", [](const RasterDataset& r) { return r.info().crs_wkt; },
          "WKT of the raster's CRS; empty when it has none.")
      .def_property_readonly("band_descriptions",
                             [](const RasterDataset& r) { return r.info().band_descriptions; })
      .def(
          "read",
          [](const RasterDataset& r, int band, const std::optional<std::vector<int>>& window,
             bool as_float) {
            const PixelWindow w = WindowOf(r, window);
            cv::Mat mat = WithoutGil(
                [&] { return as_float ? r.ReadWindowFloat(band, w) : r.ReadWindow(band, w); });
            return ArrayFromMat(std::move(mat));
          },
          py::arg("band") = 1, py::arg("window") = py::none(), py::arg("as_float") = true,
          "Reads band `band` (1-based) in window (col0, row0, width, height) [px] (default: the "
          "whole raster) as a (height, width) array. as_float: float32 with scale and offset "
          "applied and nodata (or non-finite values) as NaN; else the stored type (uint8, "
          "uint16, int16, int32, float32 or float64). Raises areomap.Error for a window outside "
          "the raster or a bad band.")
      .def(
          "window_geotransform",
          [](const RasterDataset& r, const std::vector<int>& window) {
            const std::optional<GeoTransform>& t = r.info().geotransform;
            if (!t) return std::optional<std::vector<double>>();
            const PixelWindow w = WindowOf(r, window);
            const Eigen::Vector2d origin = t->PixelToMap(w.col0, w.row0);
            GeoTransform shifted = *t;
            shifted.c[0] = origin.x();
            shifted.c[3] = origin.y();
            return GeoTransformList(shifted);
          },
          py::arg("window"),
          "The geotransform of a window's array (its pixel (0, 0) at the window's corner), or "
          "None for a plain image.")
      .def("__repr__", [](const RasterDataset& r) {
        return "<areomap.Raster " + r.info().path.string() + " " + std::to_string(r.info().width) +
               "x" + std::to_string(r.info().height) + ">";
      });
}

}  // namespace areomap::python
