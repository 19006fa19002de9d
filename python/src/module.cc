// The extension module areomap._areomap: thin bindings over the areomap libraries (the package
// areomap/__init__.py re-exports them). areomap::Error becomes areomap.Error with the same
// message.
#include <cstdint>

#include <pybind11/pybind11.h>

#include "areomap/map/error.h"
#include "bindings.h"
#include "convert.h"

namespace py = pybind11;

PYBIND11_MODULE(_areomap, m) {
  m.doc() =
      "areomap: Mars orbital-ground registration and mapping (bindings over the C++ libraries). "
      "Units: metres and degrees at this interface unless a name says otherwise; pixels in the "
      "GDAL convention (pixel (col, row) covers [col, col+1) x [row, row+1)) for rasters, JPL's "
      "(first pixel centre at (0, 0)) for camera models.";
  py::register_exception<areomap::Error>(m, "Error", PyExc_RuntimeError);
  areomap::python::BindGeodesy(m);
  areomap::python::BindCamera(m);
  areomap::python::BindRaster(m);
  areomap::python::BindCrater(m);
  areomap::python::BindRegistration(m);
  m.def(
      "_image_view_address",
      [](const py::array& image) {
        return reinterpret_cast<uintptr_t>(areomap::python::ImageView(image, "image").data);
      },
      py::arg("image"),
      "Address of the pixels the bindings read for a 2-D array (diagnostics: equal to the "
      "array's own data address when it is used without a copy).");
}
