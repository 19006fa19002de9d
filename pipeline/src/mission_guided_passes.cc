// The guided passes of a mission run (RunGuidedPasses, mission_units.h): sites matched again
// around their adjusted poses, and the adjustment repeated with their control points.
#include <cmath>

#include <tbb/parallel_for.h>

#include "areomap/map/error.h"
#include "mission_units.h"

namespace areomap::mission_run {

namespace fs = std::filesystem;
using nlohmann::json;

AdjustmentResult AdjustTraverse(const AdjustmentInputs& adjustment,
                                const ProgressCallback& progress) {
  std::vector<fs::path> inputs = {adjustment.dir / "network.json"};
  inputs.insert(inputs.end(), adjustment.site_controls.begin(), adjustment.site_controls.end());
  inputs.insert(inputs.end(), adjustment.leg_tie_files.begin(), adjustment.leg_tie_files.end());
  return AdjustmentResult::FromJson(
      areomap::AdjustTraverse(inputs, adjustment.dir, adjustment.options, progress),
      (adjustment.dir / "adjustment.json").string() + " (figures)");
}

namespace {

// Which sites a guided pass looks at, from their first registration.
struct SiteRegistrationState {
  std::vector<bool> registered;    // Matched with control points (first or a guided pass).
  std::vector<bool> eligible;      // Enough valid template pixels to try again.
  std::vector<bool> turn_at_edge;  // Matched at the rotation grid's edge (first pass only).
};

SiteRegistrationState FirstRegistrations(const RunContext& run,
                                         const std::vector<SiteUnitResult>& sites) {
  const OrbitalMatchOptions& match = run.options->match;
  SiteRegistrationState s;
  for (const SiteUnitResult& site : sites) {
    const SiteRegistrationResult& r = site.registration;
    const bool registered = r.Registered();
    const double turn = std::abs(r.rotation_deg.value_or(0.0));
    s.registered.push_back(registered);
    s.eligible.push_back(r.template_pixels >= match.min_template_pixels);
    s.turn_at_edge.push_back(registered && match.max_rotation_deg > 0.0 &&
                             turn >= match.max_rotation_deg - 0.5 * match.rotation_step_deg);
  }
  return s;
}

// One attempted site of a pass, as summary.json records it.
GuidedAttemptRecord AttemptRecord(const GuidedUnitResult& result, bool turn_at_edge) {
  const SiteRegistrationResult& r = result.registration;
  return {result.site,        result.prior,     r.matched,
          r.reason,           r.correlation,    r.null_highest_correlation,
          r.search_radius_px, r.control_points, turn_at_edge};
}

// The sites pass `pass` matches again: those not registered with enough template pixels, and in
// the first pass those whose turn was at the rotation grid's edge.
std::vector<size_t> SitesToTry(const SiteRegistrationState& state, int pass) {
  std::vector<size_t> todo;
  for (size_t i = 0; i < state.registered.size(); ++i) {
    if ((!state.registered[i] && state.eligible[i]) || (pass == 1 && state.turn_at_edge[i])) {
      todo.push_back(i);
    }
  }
  return todo;
}

}  // namespace

GuidedPassesResult RunGuidedPasses(const RunContext& run, const std::vector<SiteUnitResult>& sites,
                                   AdjustmentInputs& adjustment, AdjustmentResult& adjusted,
                                   const std::function<void()>& announce) {
  const MissionManifest& mission = *run.mission;
  const size_t site_count = mission.sites.size();
  SiteRegistrationState state = FirstRegistrations(run, sites);
  GuidedPassesResult guided;
  for (size_t i = 0; i < site_count; ++i) {
    if (state.registered[i]) guided.registered_first_pass.push_back(mission.sites[i].site);
  }
  guided.first_adjustment = adjusted;
  const fs::path adjustment_json = adjustment.dir / "adjustment.json";
  for (int pass = 1; pass <= run.options->guided_passes; ++pass) {
    const std::vector<size_t> todo = SitesToTry(state, pass);
    if (todo.empty() || !mission.FirstOrbital("image")) break;
    if (announce) announce();
    const json adjusted_sites = ReadJsonOrNull(adjustment_json).value("sites", json());
    if (!adjusted_sites.is_array() || adjusted_sites.size() != site_count) {
      throw Error(adjustment_json.string() + ": expected " + std::to_string(site_count) + " sites");
    }
    std::vector<GuidedUnitResult> results(todo.size());
    tbb::parallel_for(size_t{0}, todo.size(), [&](size_t k) {
      const GuidedPrior prior =
          GuidedPriorFromAdjustment(adjusted_sites[todo[k]], run.options->guided_sigma_floor_m);
      results[k] = RunGuidedRegistrationUnit(run, todo[k], pass, prior);
    });
    GuidedPassRecord record;
    record.pass = pass;
    for (size_t k = 0; k < todo.size(); ++k) {
      const size_t i = todo[k];
      const int site = mission.sites[i].site;
      record.attempted.push_back(AttemptRecord(results[k], state.turn_at_edge[i]));
      if (results[k].registration.Registered()) {
        (state.registered[i] ? record.replaced : record.registered).push_back(site);
        state.registered[i] = true;
        adjustment.site_controls[i] = GuidedDir(run, pass, site) / "control_points.json";
      }
      state.turn_at_edge[i] = false;
    }
    const bool any = !record.registered.empty() || !record.replaced.empty();
    if (any) {
      adjusted = AdjustTraverse(adjustment);
      record.adjustment = adjusted;
    }
    guided.passes.push_back(record);
    if (!any) break;
  }
  return guided;
}

}  // namespace areomap::mission_run
