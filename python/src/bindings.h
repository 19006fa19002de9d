// The parts of the extension module areomap._areomap, one per library area.
#pragma once

#include <pybind11/pybind11.h>

namespace areomap::python {

void BindGeodesy(pybind11::module_& m);       // bodies, coordinate systems, conversions
void BindCamera(pybind11::module_& m);        // CAHV/CAHVOR/CAHVORE and pinhole models
void BindRaster(pybind11::module_& m);        // GDAL rasters read by windows
void BindCrater(pybind11::module_& m);        // crater detection and catalogues
void BindRegistration(pybind11::module_& m);  // orthophoto-to-orbital registration

}  // namespace areomap::python
