// Rover camera models: CAHV, CAHVOR, CAHVORE (MER/MSL labels) and pinhole (.tsai).
#include <limits>
#include <string>
#include <variant>
#include <vector>

#include <pybind11/eigen.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "areomap/map/camera_linearize.h"
#include "areomap/map/camera_models.h"
#include "areomap/map/rigid3d.h"
#include "bindings.h"
#include "convert.h"

namespace areomap::python {
namespace {

// The model's components by their label names (C A H V O R E T P; pinhole: the .tsai fields).
py::dict Parameters(const CameraModel& model) {
  py::dict d;
  const auto vec = [](const Eigen::Vector3d& v) {
    return std::vector<double>{v.x(), v.y(), v.z()};
  };
  if (const auto* m = std::get_if<CahvorModel>(&model.variant())) {
    d["C"] = vec(m->c);
    d["A"] = vec(m->a);
    d["H"] = vec(m->h);
    d["V"] = vec(m->v);
    if (m->HasDistortion()) {
      d["O"] = vec(m->o);
      d["R"] = vec(m->r);
    }
  } else if (const auto* e = std::get_if<CahvoreModel>(&model.variant())) {
    d["C"] = vec(e->c);
    d["A"] = vec(e->a);
    d["H"] = vec(e->h);
    d["V"] = vec(e->v);
    d["O"] = vec(e->o);
    d["R"] = vec(e->r);
    d["E"] = vec(e->e);
    d["T"] = e->type;
    d["P"] = e->parameter;
  } else {
    const auto& p = std::get<PinholeModel>(model.variant());
    d["fu"] = p.fu;
    d["fv"] = p.fv;
    d["cu"] = p.cu;
    d["cv"] = p.cv;
    d["u_direction"] = vec(p.u_direction);
    d["v_direction"] = vec(p.v_direction);
    d["w_direction"] = vec(p.w_direction);
    d["C"] = vec(p.center);
    d["R"] = py::cast(p.world_from_camera);
    d["k1"] = p.k1;
    d["k2"] = p.k2;
    d["p1"] = p.p1;
    d["p2"] = p.p2;
    d["pitch"] = p.pitch;
  }
  return d;
}

}  // namespace

void BindCamera(py::module_& m) {
  py::class_<Rigid3d>(m, "Rigid3d",
                      "Rigid transform b_from_a between frames: p_in_b = rotation p_in_a + "
                      "translation [m].")
      .def(py::init<const Eigen::Matrix3d&, const Eigen::Vector3d&>(), py::arg("rotation"),
           py::arg("translation"),
           "From a 3x3 rotation matrix (b_from_a) and a translation in b [m].")
      .def_property_readonly("rotation", &Rigid3d::RotationMatrix, "3x3 rotation matrix.")
      .def_property_readonly(
          "quaternion",
          [](const Rigid3d& t) {
            return std::vector<double>{t.rotation.w(), t.rotation.x(), t.rotation.y(),
                                       t.rotation.z()};
          },
          "Rotation as a unit quaternion (w, x, y, z).")
      .def_readonly("translation", &Rigid3d::translation, "Translation in frame b [m].")
      .def("matrix", &Rigid3d::ToMatrix, "3x4 matrix [R | t].")
      .def("inverse", &Rigid3d::Inverse, "a_from_b.")
      .def("__mul__", [](const Rigid3d& a, const Rigid3d& b) { return a * b; });

  py::class_<CameraModel>(
      m, "CameraModel",
      "A CAHV, CAHVOR, CAHVORE or pinhole camera model in the frame its file names (e.g. "
      "ROVER_FRAME). Pixels are (column, row) with the first pixel's centre at (0, 0) (JPL's "
      "convention; add 0.5 for GDAL pixel coordinates); points in metres.")
      .def_property_readonly("type", &CameraModel::TypeName,
                             "'CAHV', 'CAHVOR', 'CAHVORE' or 'PINHOLE'.")
      .def_property_readonly("center", &CameraModel::Center, "Camera centre C [m].")
      .def_property_readonly("parameters", &Parameters,
                             "Components by their label names: C A H V [O R] [E T P] for the "
                             "CAHV family, the .tsai fields for a pinhole model.")
      .def(
          "project",
          [](const CameraModel& model, const py::object& points) {
            bool single = false;
            const std::vector<Eigen::Vector3d> in = PointsFromArray<3>(points, "points", &single);
            std::vector<Eigen::Vector2d> out(in.size());
            WithoutGil([&] {
              for (size_t i = 0; i < in.size(); ++i) {
                out[i] = model.Project(in[i]).value_or(
                    Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
              }
            });
            return ArrayFromPoints<2>(out, single);
          },
          py::arg("points"),
          "Pixels (N, 2) of points (N, 3) [m] in the model's frame; NaN for a point behind the "
          "camera or outside the model (CAHVORE). Pixels off the image are returned as they are.")
      .def(
          "unproject",
          [](const CameraModel& model, const py::object& pixels) {
            bool single = false;
            const std::vector<Eigen::Vector2d> in = PointsFromArray<2>(pixels, "pixels", &single);
            std::vector<Eigen::Vector3d> origins(in.size()), directions(in.size());
            WithoutGil([&] {
              for (size_t i = 0; i < in.size(); ++i) {
                const CameraRay ray = model.Unproject(in[i]);
                origins[i] = ray.origin;
                directions[i] = ray.direction;
              }
            });
            return py::make_tuple(ArrayFromPoints<3>(origins, single),
                                  ArrayFromPoints<3>(directions, single));
          },
          py::arg("pixels"),
          "The rays pixels (N, 2) see: (origins (N, 3) [m], unit directions (N, 3)) in the "
          "model's frame. The origin is the camera centre, or CAHVORE's entrance pupil point.")
      .def("transformed", &CameraModel::Transformed, py::arg("b_from_a"),
           "The same camera in frame b, given b_from_a for its current frame a (a Rigid3d).")
      .def(
          "linearize",
          [](const CameraModel& model, std::pair<int, int> input_size,
             std::optional<std::pair<int, int>> output_size) {
            const Eigen::Vector2i in(input_size.first, input_size.second);
            const Eigen::Vector2i out =
                output_size ? Eigen::Vector2i(output_size->first, output_size->second) : in;
            return CameraModel(LinearizeToCahv(model, in, out));
          },
          py::arg("input_size"), py::arg("output_size") = py::none(),
          "The CAHV model that resamples the image without distortion (JPL's minimum field of "
          "view linearization, as `areomap camera linearize`): sizes are (width, height) [px]; "
          "output_size defaults to input_size.")
      .def("__repr__", [](const CameraModel& model) {
        return "<areomap.CameraModel " + model.TypeName() + ">";
      });

  py::class_<CameraFile>(m, "CameraFile", "A camera model and what its file says about it.")
      .def_readonly("model", &CameraFile::model)
      .def_readonly("frame", &CameraFile::frame, "Frame of the model, e.g. 'ROVER_FRAME'.")
      .def_readonly("site_from_frame", &CameraFile::site_from_frame,
                    "Rigid3d SITE_FRAME <- model frame from the label's rover coordinate system, "
                    "or None.")
      .def_readonly("site", &CameraFile::site, "SITE_FRAME index, -1 when unknown.")
      .def_property_readonly(
          "image_size",
          [](const CameraFile& f) -> std::optional<std::pair<int, int>> {
            if (!f.image_size) return std::nullopt;
            return std::make_pair(f.image_size->x(), f.image_size->y());
          },
          "(width, height) [px] from the label's IMAGE group, or None.")
      .def_readonly("source", &CameraFile::source, "The file read.");

  m.def(
      "read_camera",
      [](const std::filesystem::path& path) {
        return WithoutGil([&] { return ReadCameraForImage(path); });
      },
      py::arg("path"),
      "Reads the camera model of a product with a PDS3/VICAR label (MER .IMG), a generator "
      "label (.json), an ASP .tsai file, or an image with one of those beside it (as `areomap "
      "camera show FILE`). Raises areomap.Error naming the file when it has no model.");
}

}  // namespace areomap::python
