// Private plumbing of RunMission (mission_run.h): the unit folders, their completion markers, the
// units under their claims around the public jobs (mission_jobs.h), and the stages' helpers. Each
// unit reads its inputs from the mission or from earlier units' files and writes its products
// atomically, its unit.json last.
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/adjustment/traverse_adjustment.h"
#include "areomap/landmarks/rock_extraction.h"
#include "areomap/landmarks/rock_matching.h"
#include "areomap/map/dtm.h"
#include "areomap/map/error.h"
#include "areomap/map/mission_manifest.h"
#include "areomap/map/orthophoto.h"
#include "areomap/map/output_folder.h"
#include "areomap/map/rigid3d.h"
#include "areomap/map/site_georeference.h"
#include "areomap/pipeline/mission_jobs.h"
#include "areomap/pipeline/mission_run.h"
#include "areomap/pipeline/unit_claim.h"
#include "areomap/pipeline/unit_results.h"
#include "areomap/pipeline/work_plan.h"

namespace areomap::mission_run {

// The shared context of one run: the jobs' (mission_jobs.h), and what resuming and claiming
// units needs.
struct RunContext : MissionRunContext {
  std::string fingerprint;  // Options + mission, recorded in every unit.json.
  UnitClaimOptions claims;  // Units are claimed (unit_claim.h): one process computes each.

  RunContext(const MissionManifest& mission_in, const MissionRunOptions& options_in,
             std::filesystem::path out_dir_in);
};

// The output-folder policy (output_folder.h) of a run's folder, planned or not: the units'
// folders, the run's files and the plan's (plan.json, claims, executor scripts and logs).
OutputFolderOptions RunFolderPolicy(const std::filesystem::path& mission, bool overwrite);

std::filesystem::path SiteDir(const MissionRunContext& run, int site);
std::filesystem::path LegDir(const MissionRunContext& run, int site_a, int site_b);

// The unit's recorded summary when it finished with this run's fingerprint and every file it
// wrote is still in its folder (a deleted points.ply makes the unit run again), else null.
nlohmann::json FinishedUnit(const RunContext& run, const std::filesystem::path& unit_dir);
// The same read as the unit's result (unit_results.h); nullopt when not finished. Throws
// areomap::Error naming unit.json and the field when the summary is not the unit's.
template <typename Result>
std::optional<Result> FinishedUnitResult(const RunContext& run,
                                         const std::filesystem::path& unit_dir) {
  const nlohmann::json summary = FinishedUnit(run, unit_dir);
  if (summary.is_null()) return std::nullopt;
  return Result::FromJson(summary, (unit_dir / "unit.json").string() + ": summary");
}
// Marks the unit finished: writes unit.json = {fingerprint, files, summary} atomically, where
// files names the unit's products (the files now in its folder, but unit.json and hidden ones).
void FinishUnit(const RunContext& run, const std::filesystem::path& unit_dir,
                const nlohmann::json& summary);

class SiteRocksCache;

// A unit under its claim (ClaimFile(run.out_dir, unit_id)): its result when FinishedUnitResult
// finds it and `accept` (if given) takes it (`*reused` true), else `compute`d and recorded by
// FinishUnit (unless `compute` wrote no folder: nothing to record). Waits while another process
// computes it. A failure leaves error.txt in `unit_dir` and throws areomap::Error with the message.
template <typename Result>
Result EnsureUnit(const RunContext& run, const std::string& unit_id,
                  const std::filesystem::path& unit_dir, const std::function<Result()>& compute,
                  bool* reused = nullptr,
                  const std::function<bool(const Result&)>& accept = nullptr) {
  std::optional<Result> result;
  std::string error;
  const UnitOutcome outcome = RunClaimedUnit(
      ClaimFile(run.out_dir, unit_id), unit_dir / "error.txt", unit_id,
      [&] {
        result = FinishedUnitResult<Result>(run, unit_dir);
        return result.has_value() && (!accept || accept(*result));
      },
      [&] {
        result = compute();
        if (std::filesystem::exists(unit_dir)) FinishUnit(run, unit_dir, result->ToJson());
      },
      run.claims, /*wait=*/true, &error);
  if (outcome == UnitOutcome::kFailed || !result) throw Error(error);
  if (reused) *reused = outcome == UnitOutcome::kReused;
  return std::move(*result);
}

// Unit ids of the plan (mission_plan.h): "site_NNN", "leg_NNN_MMM", "leg_NNN_MMM_pass2"; the
// first two name the units' folders too (SiteDir, LegDir).
std::string SiteUnitId(int site);
std::string LegUnitId(int site_a, int site_b);
std::string SecondPassUnitId(int site_a, int site_b);

// The site unit of mission.sites[site_index] (RegisterSite), computed or reused.
SiteUnitResult EnsureSiteUnit(const RunContext& run, size_t site_index,
                              const ProgressCallback& progress, bool* reused = nullptr);
// The first pass of the leg from mission.sites[index_a] to the next site (MatchLeg with the run's
// matching options and `rocks`), computed or reused. Throws areomap::Error naming
// the site unit when one of its sites is not finished.
LegUnitResult EnsureLegUnit(const RunContext& run, size_t index_a, SiteRocksCache& rocks,
                            const ProgressCallback& progress, bool* reused = nullptr);
// The rock tie points' a-posteriori variance factor pooled over the legs' first passes
// (PoolVarianceFactor), and summary.json's record of it and of the factor applied.
PooledVarianceFactor FirstPassTieVariance(const std::vector<LegUnitResult>& legs);
TieVarianceRecord TieVariance(const PooledVarianceFactor& pooled, std::optional<double> applied);
// The variance factor the legs' second pass applies given every leg's summary (first pass or
// after): the pooled factor (MissionRunOptions::RockVariancePassFactor), nullopt when the pass
// does not apply.
std::optional<double> SecondPassFactor(const RunContext& run,
                                       const std::vector<LegUnitResult>& legs);
// The second pass of leg `index_a` (its summary in `leg`, updated): matched again with the run's
// matching options and `factor` (the run's own tie_variance_factor when nullopt) unless it
// already was with that factor. Returns whether it was matched again.
bool EnsureLegSecondPass(const RunContext& run, size_t index_a, SiteRocksCache& rocks,
                         std::optional<double> factor, LegUnitResult& leg,
                         const ProgressCallback& progress);
// The craters unit (craters/), computed or reused; nullopt when craters are off.
std::optional<CratersUnitResult> EnsureCratersUnit(const RunContext& run,
                                                   const ProgressCallback& progress,
                                                   bool* reused = nullptr);
double SecondsSince(std::chrono::steady_clock::time_point start);

// The JSON in `path`; null when the file is missing or not JSON.
nlohmann::json ReadJsonOrNull(const std::filesystem::path& path);

// Guided re-registration after the first adjustment (MissionRunOptions::guided_passes): each
// pass matches again the sites that did not register (with enough template pixels) around
// their adjusted poses, and in the first pass also those whose match turned the orthophoto by
// the most the rotation grid allows; a site that registers swaps its control points in
// `adjustment` and the adjustment is repeated (`adjusted` updated). Stops when a pass
// registers nothing. Returns summary.json's "guided_registration". `announce` is called before
// each pass that has sites to try.
GuidedPassesResult RunGuidedPasses(const RunContext& run, const std::vector<SiteUnitResult>& sites,
                                   AdjustmentInputs& adjustment, AdjustmentResult& adjusted,
                                   const std::function<void()>& announce);

// Where telemetry puts a site: traverse_from_site with the believed (level, north-up) frame.
Rigid3d TelemetryTraverseFromSite(const MissionSitePose& pose);
// Distance driven from site 0 to `site_index` along the telemetry traverse [m].
double DrivenDistance(const MissionManifest& mission, size_t site_index);

// Each site's rocks (ExtractRocks on its points.ply with the run's options), extracted on first
// use and kept for the rest of the run: a site is shared by two legs, and a second pass over the
// legs (MissionRunOptions::rock_variance_pass) matches them again. A site's rocks are a few
// hundred peaks with their models, small beside its cloud, which is not kept. Not thread-safe.
class SiteRocksCache {
 public:
  struct Entry {
    SiteRocks rocks;
    RockExtractionSummary summary;
  };
  explicit SiteRocksCache(const MissionRunContext& run) : run_(&run) {}
  // Throws areomap::Error (from the PLY reader) naming the file when it cannot be read.
  const Entry& Get(size_t site_index);

 private:
  const MissionRunContext* run_;
  std::map<size_t, Entry> entries_;
};

// Stage of one leg (consecutive site indices): rocks, matching with `matching` (the run's
// options, or the second pass's with its variance factor), fault detection, tie points. Writes
// the leg's folder (LegDir) except unit.json.
LegUnitResult RunLegUnit(const MissionRunContext& run, size_t index_a, size_t index_b,
                         SiteRocksCache& rocks, const RockMatchingOptions& matching,
                         const ProgressCallback& progress);

// The legs' tie points tested against each other (MissionRunOptions::leg_test, leg_consistency.h)
// once every leg unit has finished. Each leg in `legs` (one per consecutive pair, as RunLegUnit
// returned it) gains its leg_test (the verdict; the dropped tie points' ids) and the test's rule
// in its faults; a leg the test changed gets its remaining tie points in
// `ties_dir`/leg_NNN_MMM.json, its RE re-evaluated (eq. 4.9, a rule too) and, if excluded, the
// outcome "excluded by fault detection". Returns each leg's tie point file for the adjustment.
std::vector<std::filesystem::path> TestLegsAgainstEachOther(const RunContext& run,
                                                            std::vector<LegUnitResult>& legs,
                                                            const std::filesystem::path& ties_dir);
// Orbital registration of a site's orthophoto (`ortho`, read from or written to `ortho_path`, at
// its telemetry georeference) around `prior` with `options`: the library's job (RegisterOrthoImage,
// ortho_registration.h, that `areomap register` runs too) without its edge verification, on the
// mission's first orbital image with heights from its first orbital DTM. Writes
// registration.json, correlation_surface.png and control_points.json (BA input format, ids
// "site<N>-...") into `dir` and returns the registration. Without an orbital image: skipped.
SiteRegistrationResult RegisterSiteOrtho(const MissionRunContext& run, const Orthophoto& ortho,
                                         const std::filesystem::path& ortho_path, int site,
                                         const OrbitalPrior& prior,
                                         const OrbitalMatchOptions& options,
                                         const std::filesystem::path& dir);

// The guided prior of a site from its entry of adjustment.json (BundleResult's JSON: initial
// and adjusted poses, 6 x 6 covariance); throws areomap::Error naming the site and field.
GuidedPrior GuidedPriorFromAdjustment(const nlohmann::json& adjusted_site, double sigma_floor_m);
// guided/pass_P/site_NNN/: registration.json, control_points.json, unit.json (the summary
// records the prior; a finished unit is reused only when the prior and guided settings match).
std::filesystem::path GuidedDir(const RunContext& run, int pass, int site);
GuidedUnitResult RunGuidedRegistrationUnit(const RunContext& run, size_t site_index, int pass,
                                           const GuidedPrior& prior);

// The left image of every stereo pair of a site with its camera in the site frame, the
// orthophoto's sources; ids are first_id, first_id + 1, ...
std::vector<OrthoSourceImage> SiteOrthoImages(const MissionSite& site, int first_id);

// Whether a finished products unit's recorded "poses" are `traverse_from_site` (to 0.1 mm /
// 1e-4 in the quaternion: above solver round-off, far below the products' posting).
bool SamePoses(const std::vector<std::array<double, 7>>& recorded,
               const std::vector<Rigid3d>& traverse_from_site);

}  // namespace areomap::mission_run
