// The units of a mission run (mission_run.h) as typed jobs: each takes the mission, the run's
// options and its folder (MissionRunContext), writes its products into its own folder under the
// run folder, and returns its result (unit_results.h). RunMission and `areomap run-unit` run them
// under claims, resume finished ones and record each as its folder's unit.json; a caller of a job
// here gets none of that: the job computes, and writes everything but unit.json.
//
// Folders: sites/site_NNN/ (RegisterSite), legs/leg_NNN_MMM/ (MatchLeg), craters/
// (DetectOrbitalCraters), adjustment/ (AdjustTraverse), products/ (MakeTraverseProducts). Units
// are as unit_results.h says. Failure: a job throws areomap::Error naming the file or step that
// failed (a missing input of an earlier job included: MatchLeg needs both sites' points.ply,
// AdjustTraverse every file it names, and throws before writing anything); what it wrote stays.
#pragma once

#include <cstddef>
#include <filesystem>
#include <vector>

#include "areomap/adjustment/traverse_adjustment.h"
#include "areomap/landmarks/rock_matching.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/progress.h"
#include "areomap/map/rigid3d.h"
#include "areomap/map/site_georeference.h"
#include "areomap/pipeline/mission_run.h"
#include "areomap/pipeline/unit_results.h"

namespace areomap::mission_run {

// What the jobs of one run share: the mission, the options, the run folder and the mission map
// (equirectangular at the mission's origin). Holds pointers: `mission` and `options` must
// outlive it.
struct MissionRunContext {
  const MissionManifest* mission;
  const MissionRunOptions* options;
  std::filesystem::path out_dir;
  MapFrame map;

  MissionRunContext(const MissionManifest& mission_in, const MissionRunOptions& options_in,
                    std::filesystem::path out_dir_in);
};

// Site mission.sites[site_index]: dense stereo of each pair, points.ply, DTM, orthophoto and its
// registration on the mission's first orbital image (skipped without one), with the control
// points for the adjustment; "seconds" per stage.
SiteUnitResult RegisterSite(const MissionRunContext& run, size_t site_index,
                            const ProgressCallback& progress = nullptr);

// The leg from mission.sites[index_a] to the next site: both sites' rocks (from their
// points.ply), matching with `matching`, fault detection, the tie points; its wall time in
// match.seconds.
LegUnitResult MatchLeg(const MissionRunContext& run, size_t index_a,
                       const RockMatchingOptions& matching,
                       const ProgressCallback& progress = nullptr);

// Craters on the mission's first orbital image: catalogue (CSV, JSON, GeoPackage), overlay PNG,
// and the score against truth/craters.csv when the mission has it. Skipped (`skipped`) without
// an orbital image. `seconds` is left 0: the run records the unit's wall time around the job.
CratersUnitResult DetectOrbitalCraters(const MissionRunContext& run,
                                       const ProgressCallback& progress = nullptr);

// The bundle adjustment's inputs: `dir` holds network.json (the mission's sites and legs) and
// receives adjustment.json and its files; one control point file per mission site (as
// RegisterSite writes it) and one tie point file per leg (as MatchLeg writes it).
struct AdjustmentInputs {
  std::filesystem::path dir;
  std::vector<std::filesystem::path> site_controls;
  std::vector<std::filesystem::path> leg_tie_files;
  TraverseAdjustmentOptions options;
};
// AdjustTraverse (traverse_adjustment.h) on network.json, the site controls and the leg ties;
// its figures.
AdjustmentResult AdjustTraverse(const AdjustmentInputs& inputs,
                                const ProgressCallback& progress = nullptr);

// The whole traverse: every site's points.ply gridded into one DTM with `traverse_from_site`
// (one pose per mission site, the adjusted ones in a run), each site's images draped on it and
// blended into one orthomosaic; both compared with the orbital DTM and image when the mission
// has them, and the DTM made with the telemetry poses too. The poses are in `poses`.
ProductsUnitResult MakeTraverseProducts(const MissionRunContext& run,
                                        const std::vector<Rigid3d>& traverse_from_site,
                                        const ProgressCallback& progress = nullptr);

}  // namespace areomap::mission_run
