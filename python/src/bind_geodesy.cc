// Bodies and coordinate systems: what `areomap coords` converts, vectorised over N x 3 arrays.
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include <pybind11/stl.h>

#include "areomap/map/body.h"
#include "areomap/map/coordinate_system.h"
#include "areomap/map/geodesy.h"
#include "bindings.h"
#include "convert.h"

namespace areomap::python {
namespace {

// The context of a conversion: the body (None: IAU 2000 ellipsoid, or the datum of a raster or
// CRS on the other side) and the origin of enu/site frames in degrees and metres.
CoordinateSystemContext Context(const std::optional<Body>& body,
                                const std::optional<std::vector<double>>& origin_deg) {
  CoordinateSystemContext context;
  if (body) context.body = *body;
  if (origin_deg) {
    if (origin_deg->size() != 2 && origin_deg->size() != 3) {
      throw Error("origin: expected (lat, lon[, h]) in degrees and metres, got " +
                  std::to_string(origin_deg->size()) + " numbers");
    }
    context.origin = Geographic{RadFromDeg((*origin_deg)[0]), RadFromDeg((*origin_deg)[1]),
                                origin_deg->size() == 3 ? (*origin_deg)[2] : 0.0};
  }
  return context;
}

}  // namespace

void BindGeodesy(py::module_& m) {
  py::class_<Body>(m, "Body",
                   "A biaxial ellipsoid or sphere: equatorial radius a and polar radius b [m].")
      .def(py::init([](double a, double b, const std::string& name) {
             Body body{name, a, b};
             body.Check();
             return body;
           }),
           py::arg("a"), py::arg("b"), py::arg("name") = "custom",
           "A body of radii a >= b > 0 [m]; raises areomap.Error otherwise.")
      .def_readonly("name", &Body::name)
      .def_readonly("a", &Body::a, "Equatorial radius [m].")
      .def_readonly("b", &Body::b, "Polar radius [m].")
      .def_property_readonly("flattening", &Body::Flattening, "(a - b) / a.")
      .def_static("mars2000", &Body::Mars2000,
                  "IAU 2000 Mars ellipsoid, a = 3396190 m, b = 3376200 m (the default).")
      .def_static("mars_sphere", &Body::MarsSphere, "IAU Mars sphere, R = 3396190 m.")
      .def_static("mola_sphere", &Body::MolaSphere, "MOLA reference sphere, R = 3396000 m.")
      .def_static("sphere", &Body::Sphere, py::arg("radius"), py::arg("name") = "sphere",
                  "A sphere of radius `radius` [m].")
      .def_static("from_name", &Body::FromName, py::arg("name"),
                  "'mars2000', 'mars-sphere' or 'mola-sphere' (case-insensitive).")
      .def_static("names", &Body::Names)
      .def("__eq__", [](const Body& a, const Body& b) { return a == b; })
      .def("__repr__", [](const Body& b) {
        return "Body(a=" + std::to_string(b.a) + ", b=" + std::to_string(b.b) + ", name='" +
               b.name + "')";
      });

  py::class_<CoordinateSystem>(m, "CoordinateSystem",
                               "One coordinate system of `areomap coords` (see Conversion).")
      .def_property_readonly("spec", &CoordinateSystem::spec)
      .def("decimals", &CoordinateSystem::Decimals, py::arg("component"),
           "Decimals `areomap coords` prints for component 0, 1 or 2 (12 for degrees, 6 for "
           "metres and pixels).")
      .def_property_readonly("datum_body", &CoordinateSystem::DatumBody,
                             "The body of a raster:, pixel: or CRS system's datum; None for "
                             "the others.");

  py::class_<CoordinateConversion>(
      m, "Conversion",
      "Converts points between two systems through Mars body-fixed XYZ, as `areomap coords "
      "--from FROM --to TO` does.\n\n"
      "Systems: 'mbf' (X Y Z [m]); 'planetocentric[,west][,360]' and "
      "'planetographic[,west][,360]' (lat lon [deg], h [m] above the body's ellipsoid); "
      "'spherical' (lat lon [deg], radius [m]); 'enu' (x east, y north, z up [m]) and 'site' "
      "(MER site frame: x north, y east, z down [m]) at `origin`; 'raster:PATH' (map x y of its "
      "CRS, h [m]); 'pixel:PATH' (col row, pixel centres at +0.5, h [m]); or any CRS GDAL/PROJ "
      "knows, e.g. 'IAU_2015:49910' (x/longitude first).\n\n"
      "body: a Body; None uses the datum of a raster:, pixel: or CRS system on the other side "
      "for the geographic and local systems (as the CLI without --body), else the IAU 2000 "
      "ellipsoid. origin: (lat, lon[, h]) planetocentric degrees east and metres, for "
      "enu/site.")
      .def(py::init([](const std::string& from, const std::string& to,
                       const std::optional<Body>& body,
                       const std::optional<std::vector<double>>& origin) {
             return CoordinateConversion::Make(from, to, Context(body, origin), body.has_value());
           }),
           py::arg("from_"), py::arg("to"), py::arg("body") = py::none(),
           py::arg("origin") = py::none())
      .def_readonly("from_", &CoordinateConversion::from)
      .def_readonly("to", &CoordinateConversion::to)
      .def_readonly("datum_body", &CoordinateConversion::datum_body,
                    "The datum body taken from a raster or CRS when `body` was None; None when "
                    "the given (or default) body is used.")
      .def(
          "__call__",
          [](const CoordinateConversion& conversion, const py::object& points,
             const std::string& errors) {
            if (errors != "raise" && errors != "nan") {
              throw Error("errors: expected 'raise' or 'nan', got '" + errors + "'");
            }
            bool single = false;
            const std::vector<Eigen::Vector3d> in = PointsFromArray<3>(points, "points", &single);
            std::vector<Eigen::Vector3d> out(in.size());
            WithoutGil([&] {
              for (size_t i = 0; i < in.size(); ++i) {
                try {
                  out[i] = conversion.Convert(in[i]);
                } catch (const Error& e) {
                  if (errors == "raise") {
                    throw Error("point " + std::to_string(i) + ": " + e.what());
                  }
                  out[i].setConstant(std::numeric_limits<double>::quiet_NaN());
                }
              }
            });
            return ArrayFromPoints<3>(out, single);
          },
          py::arg("points"), py::arg("errors") = "raise",
          "Converts an (N, 3) array (or one point of 3 values) in the units of the systems "
          "(degrees, metres, pixels; a 2-value point needs a third 0). errors='raise' raises "
          "areomap.Error naming the first bad point's index and why (latitude outside [-90, 90], "
          "NaN, outside the projection); errors='nan' gives NaN rows for them, as the CLI prints "
          "'nan nan nan'.");
}

}  // namespace areomap::python
