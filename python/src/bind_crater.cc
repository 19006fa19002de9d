// Crater detection on NumPy images or on rasters of any size, and the sun azimuth estimate.
#include <filesystem>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "areomap/crater/crater_output.h"
#include "areomap/crater/crater_raster.h"
#include "areomap/crater/sun_azimuth.h"
#include "areomap/map/raster.h"
#include "bindings.h"
#include "convert.h"

namespace areomap::python {
namespace {

// The catalogue as the CLI writes craters.json (CraterCatalogJson), plus its georeference.
py::dict CatalogDict(const CraterCatalog& catalog) {
  nlohmann::json json = CraterCatalogJson(catalog);
  json["pixel_size_m"] = catalog.pixel_size_m;
  json["crs_wkt"] = catalog.crs_wkt;
  if (catalog.geotransform) json["geotransform"] = catalog.geotransform->c;
  return FromJson(json);
}

}  // namespace

void BindCrater(py::module_& m) {
  using Options = CraterDetectorOptions;
  py::class_<Options>(
      m, "CraterDetectorOptions",
      "Options of the crater detector (crater_detector.h; `areomap craters --help` gives the "
      "same with their CLI names). Lengths in pixels of the input; the sun azimuth in degrees "
      "clockwise from the image's up direction, towards the sun.")
      .def(py::init<>())
      .def("__copy__", [](const Options& o) { return o; })
      .def_readwrite("min_diameter_px", &Options::min_diameter_px,
                     "Smallest rim diameter a + b reported [px], >= 4.")
      .def_readwrite("max_diameter_px", &Options::max_diameter_px,
                     "Largest rim diameter [px]; 0: no limit.")
      .def_readwrite("sun_azimuth_deg", &Options::sun_azimuth_deg,
                     "Images: sun azimuth [deg clockwise from up, towards the sun]; enables the "
                     "shading checks. None: off (estimate_sun_azimuth() can give one).")
      .def_readwrite("min_coverage", &Options::min_coverage,
                     "Fraction of 36 rim sectors that must hold edges.")
      .def_readwrite("min_shading_contrast", &Options::min_shading_contrast,
                     "Image with sun: wall contrast threshold.")
      .def_readwrite("min_edge_contrast", &Options::min_edge_contrast,
                     "Rim edge strength / the high Canny threshold.")
      .def_readwrite("min_depth_ratio", &Options::min_depth_ratio,
                     "DTM: (rim - interior height) / diameter threshold [height unit / px].")
      .def_readwrite("max_axis_ratio", &Options::max_axis_ratio, "Largest a / b accepted.")
      .def_readwrite("upsample_small_craters", &Options::upsample_small_craters,
                     "Search craters under 16 px across on a 2x upsampled copy.")
      .def_readwrite("dtm_posting", &Options::dtm_posting,
                     "DTM: ground size of a pixel in height units (turns heights into slopes).")
      .def_readwrite("tile_size", &Options::tile_size, "Rasters: tile core edge [px].")
      .def_readwrite("tile_overlap", &Options::tile_overlap,
                     "Rasters: tile margin [px]; bounds in-tile diameters.")
      .def_property(
          "shading_templates", [](const Options& o) { return o.shading_template.enabled; },
          [](Options& o, bool on) { o.shading_template.enabled = on; },
          "Images with a sun: also seek small degraded bowls by their shading (~1.35x time).")
      .def_property(
          "method", [](const Options& o) { return ToString(o.method); },
          [](Options& o, const std::string& name) { o.method = CraterMethodFromString(name); },
          "Rasters (paths) holding images: 'edges' (rim edges to ellipses) or 'learned' (the "
          "trained network, rims refitted; docs/crater-model.md). Arrays and DTMs use edges.")
      .def_property(
          "model_path", [](const Options& o) { return o.learned.model_path; },
          [](Options& o, const std::string& path) { o.learned.model_path = path; },
          "learned: ONNX model file; empty: the built-in one.")
      .def_property(
          "min_score", [](const Options& o) { return o.learned.min_score; },
          [](Options& o, double score) { o.learned.min_score = score; },
          "learned: heat-map peak threshold in (0, 1).")
      .def_property(
          "refine_rims", [](const Options& o) { return o.learned.refine_rims; },
          [](Options& o, bool on) { o.learned.refine_rims = on; },
          "learned: refit rims as ellipses where they show edges.")
      .def("check", &Options::Check, "Raises areomap.Error naming a bad field.");

  m.def(
      "_detect_craters",
      [](const py::object& image, bool dtm, const Options& options, const py::object& progress) {
        const RimSource source = dtm ? RimSource::kDtm : RimSource::kImage;
        ProgressBridge bridge(progress);
        if (py::isinstance<py::array>(image)) {
          const py::array array = py::reinterpret_borrow<py::array>(image);
          const cv::Mat view = ImageView(array, "image");
          RasterInfo info;
          info.width = view.cols;
          info.height = view.rows;
          const CraterCatalog catalog = bridge.Run([&](const ProgressCallback& callback) {
            return MakeCraterCatalog(DetectCratersInImage(view, source, options, callback), info);
          });
          return CatalogDict(catalog);
        }
        const auto path = image.cast<std::filesystem::path>();
        const CraterCatalog catalog = bridge.Run([&](const ProgressCallback& callback) {
          const RasterDataset dataset = RasterDataset::Open(path);
          return MakeCraterCatalog(DetectCratersInRaster(dataset, source, options, callback),
                                   dataset.info());
        });
        return CatalogDict(catalog);
      },
      py::arg("image"), py::arg("dtm"), py::arg("options"), py::arg("progress"));

  m.def(
      "estimate_sun_azimuth",
      [](const std::filesystem::path& path, const std::optional<Options>& detector,
         const py::object& progress) {
        ProgressBridge bridge(progress);
        const SunAzimuthEstimate estimate = bridge.Run([&](const ProgressCallback& callback) {
          const RasterDataset dataset = RasterDataset::Open(path);
          return EstimateSunAzimuthInRaster(dataset, detector.value_or(Options{}), {}, callback);
        });
        return FromJson(SunAzimuthEstimateJson(estimate));
      },
      py::arg("path"), py::arg("options") = py::none(), py::arg("progress") = py::none(),
      "The sun azimuth of an image estimated from its craters' shading (sun_azimuth.h), as "
      "`areomap craters` does when no --sun-azimuth is given: a dict with azimuth_deg [deg "
      "clockwise from the image's up direction, towards the sun; None without votes], "
      "candidates, votes, agreement and reliable. The CLI uses it only when reliable.");
}

}  // namespace areomap::python
