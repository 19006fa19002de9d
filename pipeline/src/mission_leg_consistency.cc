#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <string>

#include "areomap/adjustment/bundle_io.h"
#include "areomap/landmarks/fault_detection.h"
#include "areomap/landmarks/leg_consistency.h"
#include "areomap/landmarks/localization_error.h"
#include "areomap/map/atomic_file.h"
#include "mission_units.h"

namespace areomap::mission_run {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Where site b lies in site a's frame, for RE: the leg's prior (RunLegUnit's "prior"), or, in a
// leg unit of a run from before it recorded that, telemetry (the same up to the prior's sigma,
// which moves RE's traverse length by a few per cent at most).
Eigen::Vector2d AdjacentInCurrent(const RunContext& run, size_t leg_index,
                                  const LegUnitResult& leg) {
  if (leg.prior && leg.prior->a_from_b_translation_m) {
    const std::array<double, 3>& t = *leg.prior->a_from_b_translation_m;
    return {t[0], t[1]};
  }
  const MissionManifest& mission = *run.mission;
  const Rigid3d a_from_b = TelemetryTraverseFromSite(mission.telemetry.at(leg_index)).Inverse() *
                           TelemetryTraverseFromSite(mission.telemetry.at(leg_index + 1));
  return a_from_b.translation.head<2>();
}

void Exclude(LegUnitResult& leg) {
  leg.match.outcome = ToString(PairOutcome::kExcludedByFaultDetection);
  leg.faults.outcome = PairOutcome::kExcludedByFaultDetection;
}

}  // namespace

std::vector<fs::path> TestLegsAgainstEachOther(const RunContext& run,
                                               std::vector<LegUnitResult>& legs,
                                               const fs::path& ties_dir) {
  const MissionManifest& mission = *run.mission;
  const MissionRunOptions& options = *run.options;
  std::vector<fs::path> files;
  std::vector<std::vector<TiePoint>> ties(legs.size());
  for (size_t i = 0; i < legs.size(); ++i) {
    files.push_back(LegDir(run, mission.sites[i].site, mission.sites[i + 1].site) /
                    "tie_points.json");
    if (options.leg_test && legs[i].match.outcome == ToString(PairOutcome::kMatched)) {
      ties[i] = ReadTiePoints(files[i]);
    }
  }
  // What an earlier run's test left there is not this run's (the adjustment reads only `files`):
  // remove the files this test writes, one per leg named after the leg's folder, and nothing else
  // (a user's file or folder there stays).
  for (const fs::path& leg_file : files) {
    const fs::path earlier = ties_dir / (leg_file.parent_path().filename().string() + ".json");
    std::error_code ec;
    if (fs::is_regular_file(fs::symlink_status(earlier, ec))) fs::remove(earlier, ec);
  }
  if (!options.leg_test) return files;
  const std::vector<LegConsistency> verdicts = TestLegConsistency(ties, options.LegTestOptions());
  for (size_t i = 0; i < legs.size(); ++i) {
    const LegConsistency& v = verdicts[i];
    LegUnitResult& leg = legs[i];
    leg.leg_test = v;
    leg.leg_test_dropped_ids.clear();
    if (!v.tested) continue;
    for (int k : v.dropped) leg.leg_test_dropped_ids.push_back(ties[i][static_cast<size_t>(k)].id);
    // The rule as first tested; when tie points were dropped, again on those left (the one
    // that decides whether the leg stays).
    const char* rule = "leg's variance factor / other legs' (F test)";
    leg.faults.checks.push_back(
        MaxCheck("IV adjustment", rule, v.first_f_statistic, v.f_threshold, "", v.dropped.empty()));
    if (!v.dropped.empty()) {
      leg.faults.checks.push_back(MaxCheck(
          "IV adjustment",
          std::string(rule) + " without " + std::to_string(v.dropped.size()) + " tie point(s)",
          v.f_statistic, v.f_threshold, ""));
    }
    if (v.dropped.empty() && !v.excluded) continue;
    std::vector<TiePoint> kept;
    for (size_t k = 0; k < ties[i].size() && !v.excluded; ++k) {
      if (std::find(v.dropped.begin(), v.dropped.end(), static_cast<int>(k)) == v.dropped.end()) {
        kept.push_back(ties[i][k]);
      }
    }
    if (!kept.empty()) {
      std::vector<PlanarTiePoint> planar;
      for (const TiePoint& t : kept) planar.push_back(PlanarTie(t));
      const std::optional<SitePairError> error =
          EvaluateSitePair(planar, AdjacentInCurrent(run, i, leg));
      const double re = error ? error->relative_error_percent : std::nan("");
      leg.match.relative_error_percent = error ? std::optional<double>(re) : std::nullopt;
      const FaultCheck check =
          MaxCheck("IV adjustment", "relative error RE (eq. 4.9) after the legs' test", re,
                   options.matching.fault_detection.max_relative_error_percent, "%");
      leg.faults.checks.push_back(check);
      if (check.verdict != FaultVerdict::kPass) kept.clear();
    }
    if (kept.empty()) Exclude(leg);
    leg.match.tie_points = static_cast<int64_t>(kept.size());
    fs::create_directories(ties_dir);
    files[i] = ties_dir / (files[i].parent_path().filename().string() + ".json");
    WriteFileAtomically(files[i], json{{"tie_points", TiePointsToJson(kept)}}.dump(2));
  }
  return files;
}

}  // namespace areomap::mission_run
