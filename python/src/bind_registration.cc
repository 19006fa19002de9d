// Orthophoto-to-orbital registration (RegisterOrtho): the match with its sigma and the control
// points, as `areomap register` computes them; the bundle adjustment of a traverse network
// (AdjustTraverse), as `areomap adjust` runs it; the mission run (RunMissionFolder), as `areomap
// run`.
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "areomap/adjustment/traverse_adjustment.h"
#include "areomap/pipeline/mission_run.h"
#include "areomap/registration/orbital_report.h"
#include "areomap/registration/ortho_registration.h"
#include "bindings.h"
#include "convert.h"

namespace areomap::python {

void BindRegistration(py::module_& m) {
  m.def(
      "_register",
      [](const std::filesystem::path& ortho, const std::vector<std::filesystem::path>& orbitals,
         const std::optional<std::filesystem::path>& orbital_dtm,
         const std::optional<std::vector<double>>& prior_deg, std::optional<double> prior_height_m,
         std::optional<double> prior_sigma_m, std::optional<int> site, bool similarity,
         std::optional<double> range_m, std::optional<double> max_rotation_deg,
         std::optional<double> max_scale_change, std::optional<double> max_false_match,
         const py::object& progress) {
        // Options left None keep the library's defaults.
        OrthoRegistrationOptions options;
        options.prior_height_m = prior_height_m.value_or(options.prior_height_m);
        if (prior_deg) {
          if (prior_deg->size() != 2) {
            throw Error("prior: expected (lat, lon) in planetocentric degrees east");
          }
          options.prior_position = Geographic{RadFromDeg((*prior_deg)[0]),
                                              RadFromDeg((*prior_deg)[1]), options.prior_height_m};
        }
        options.prior_sigma_m = prior_sigma_m.value_or(options.prior_sigma_m);
        options.site = site;
        options.similarity = similarity;
        TemplateOptions& templ = options.match.template_options;
        templ.reliable_range_m = range_m.value_or(templ.reliable_range_m);
        OrbitalMatchOptions& match = options.match;
        match.max_rotation_deg = max_rotation_deg.value_or(match.max_rotation_deg);
        match.max_scale_change = max_scale_change.value_or(match.max_scale_change);
        match.max_false_match = max_false_match.value_or(match.max_false_match);
        ProgressBridge bridge(progress);
        const OrthoRegistration registration = bridge.Run([&](const ProgressCallback& callback) {
          return RegisterOrtho(ortho, orbitals, orbital_dtm, options, callback);
        });
        nlohmann::json json = OrthoRegistrationJson(registration);
        json["control_points"] = ControlPointsJson(registration.control_points);
        if (registration.corrected_geotransform) {
          json["corrected_geotransform"] = registration.corrected_geotransform->c;
        }
        return FromJson(json);
      },
      py::arg("ortho"), py::arg("orbitals"), py::arg("orbital_dtm"), py::arg("prior"),
      py::arg("prior_height_m"), py::arg("prior_sigma_m"), py::arg("site"), py::arg("similarity"),
      py::arg("range_m"), py::arg("max_rotation_deg"), py::arg("max_scale_change"),
      py::arg("max_false_match"), py::arg("progress"));

  m.def(
      "_adjust",
      [](const std::vector<std::filesystem::path>& inputs, const std::filesystem::path& out_dir,
         const std::optional<std::filesystem::path>& orbital, std::optional<double> huber,
         std::optional<double> alpha, std::optional<int> rejection_rounds,
         std::optional<double> rock_tie_variance_factor, std::optional<double> ellipse_scale,
         const py::object& progress) {
        // Options left None keep the library's defaults.
        TraverseAdjustmentOptions options;
        BundleOptions& bundle = options.bundle;
        bundle.huber_scale = huber.value_or(bundle.huber_scale);
        bundle.rejection_alpha = alpha.value_or(bundle.rejection_alpha);
        bundle.max_rejection_rounds = rejection_rounds.value_or(bundle.max_rejection_rounds);
        options.rock_tie_variance_factor =
            rock_tie_variance_factor.value_or(options.rock_tie_variance_factor);
        options.map.ellipse_scale = ellipse_scale.value_or(options.map.ellipse_scale);
        if (orbital) options.orbital_image = *orbital;
        ProgressBridge bridge(progress);
        return FromJson(bridge.Run([&](const ProgressCallback& callback) {
          return AdjustTraverse(inputs, out_dir, options, callback);
        }));
      },
      py::arg("inputs"), py::arg("out_dir"), py::arg("orbital"), py::arg("huber"), py::arg("alpha"),
      py::arg("rejection_rounds"), py::arg("rock_tie_variance_factor"), py::arg("ellipse_scale"),
      py::arg("progress"));

  m.def(
      "_run_mission",
      [](const std::filesystem::path& mission, const std::filesystem::path& out_dir,
         std::optional<bool> detect_craters, std::optional<bool> traverse_products,
         std::optional<double> crater_min_diameter_m, bool overwrite, const py::object& progress) {
        // Options left None keep the library's defaults.
        MissionRunOptions options;
        options.detect_craters = detect_craters.value_or(options.detect_craters);
        options.traverse_products = traverse_products.value_or(options.traverse_products);
        options.crater_min_diameter_m =
            crater_min_diameter_m.value_or(options.crater_min_diameter_m);
        ProgressBridge bridge(progress);
        const MissionRunSummary summary = bridge.Run([&](const ProgressCallback& callback) {
          return RunMissionFolder(mission, out_dir, options, overwrite, callback);
        });
        return FromJson(summary.json);
      },
      py::arg("mission"), py::arg("out_dir"), py::arg("detect_craters"),
      py::arg("traverse_products"), py::arg("crater_min_diameter_m"), py::arg("overwrite"),
      py::arg("progress"));
}

}  // namespace areomap::python
