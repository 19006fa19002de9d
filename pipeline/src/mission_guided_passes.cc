// The guided passes of a mission run (RunGuidedPasses, mission_units.h): sites matched again
// around their adjusted poses, and the adjustment repeated with their control points.
#include <cmath>

#include <tbb/parallel_for.h>

#include "areomap/map/error.h"
#include "mission_units.h"

namespace areomap::mission_run {

namespace fs = std::filesystem;
using nlohmann::json;

json AdjustmentStage::Run(const ProgressCallback& progress) const {
  std::vector<fs::path> inputs = {dir / "network.json"};
  inputs.insert(inputs.end(), site_controls.begin(), site_controls.end());
  inputs.insert(inputs.end(), leg_tie_files.begin(), leg_tie_files.end());
  return AdjustTraverse(inputs, dir, options, progress);
}

namespace {

// Which sites a guided pass looks at, from their first registration.
struct SiteRegistrationState {
  std::vector<bool> registered;    // Matched with control points (first or a guided pass).
  std::vector<bool> eligible;      // Enough valid template pixels to try again.
  std::vector<bool> turn_at_edge;  // Matched at the rotation grid's edge (first pass only).
};

SiteRegistrationState FirstRegistrations(const RunContext& run, const std::vector<json>& sites) {
  const OrbitalMatchOptions& match = run.options->match;
  SiteRegistrationState s;
  for (const json& site : sites) {
    const json& r = site.value("registration", json::object());
    const bool registered = r.value("matched", false) && r.value("control_points", 0) > 0;
    const double turn = std::abs(r.value("rotation_deg", 0.0));
    s.registered.push_back(registered);
    s.eligible.push_back(r.value("template_pixels", 0) >= match.min_template_pixels);
    s.turn_at_edge.push_back(registered && match.max_rotation_deg > 0.0 &&
                             turn >= match.max_rotation_deg - 0.5 * match.rotation_step_deg);
  }
  return s;
}

// One attempted site of a pass, as summary.json records it.
json AttemptRecord(int site, const json& result, bool turn_at_edge) {
  const json& r = result["registration"];
  return {{"site", site},
          {"prior", result["prior"]},
          {"matched", r.value("matched", false)},
          {"reason", r.value("reason", "")},
          {"correlation", r.value("correlation", json())},
          {"null_highest_correlation", r.value("null_highest_correlation", json())},
          {"search_radius_px", r.value("search_radius_px", 0)},
          {"control_points", r.value("control_points", 0)},
          {"turn_at_edge", turn_at_edge}};
}

}  // namespace

json RunGuidedPasses(const RunContext& run, const std::vector<json>& site_summaries,
                     AdjustmentStage& adjustment, json& adjusted,
                     const std::function<void()>& announce) {
  const MissionManifest& mission = *run.mission;
  const size_t site_count = mission.sites.size();
  SiteRegistrationState state = FirstRegistrations(run, site_summaries);
  json first_pass_sites = json::array();
  for (size_t i = 0; i < site_count; ++i) {
    if (state.registered[i]) first_pass_sites.push_back(mission.sites[i].site);
  }
  json guided = {{"registered_first_pass", first_pass_sites},
                 {"first_adjustment", adjusted},
                 {"passes", json::array()}};
  const fs::path adjustment_json = adjustment.dir / "adjustment.json";
  for (int pass = 1; pass <= run.options->guided_passes; ++pass) {
    std::vector<size_t> todo;
    for (size_t i = 0; i < site_count; ++i) {
      if ((!state.registered[i] && state.eligible[i]) || (pass == 1 && state.turn_at_edge[i])) {
        todo.push_back(i);
      }
    }
    if (todo.empty() || !mission.FirstOrbital("image")) break;
    if (announce) announce();
    const json sites = ReadJsonOrNull(adjustment_json).value("sites", json());
    if (!sites.is_array() || sites.size() != site_count) {
      throw Error(adjustment_json.string() + ": expected " + std::to_string(site_count) + " sites");
    }
    std::vector<json> results(todo.size());
    tbb::parallel_for(size_t{0}, todo.size(), [&](size_t k) {
      const GuidedPrior prior =
          GuidedPriorFromAdjustment(sites[todo[k]], run.options->guided_sigma_floor_m);
      results[k] = RunGuidedRegistrationUnit(run, todo[k], pass, prior);
    });
    json record = {{"pass", pass},
                   {"attempted", json::array()},
                   {"registered", json::array()},
                   {"replaced", json::array()}};
    for (size_t k = 0; k < todo.size(); ++k) {
      const size_t i = todo[k];
      const int site = mission.sites[i].site;
      const json& r = results[k]["registration"];
      record["attempted"].push_back(AttemptRecord(site, results[k], state.turn_at_edge[i]));
      if (r.value("matched", false) && r.value("control_points", 0) > 0) {
        record[state.registered[i] ? "replaced" : "registered"].push_back(site);
        state.registered[i] = true;
        adjustment.site_controls[i] = GuidedDir(run, pass, site) / "control_points.json";
      }
      state.turn_at_edge[i] = false;
    }
    const bool any = !record["registered"].empty() || !record["replaced"].empty();
    if (any) {
      adjusted = adjustment.Run();
      record["adjustment"] = adjusted;
    }
    guided["passes"].push_back(record);
    if (!any) break;
  }
  return guided;
}

}  // namespace areomap::mission_run
