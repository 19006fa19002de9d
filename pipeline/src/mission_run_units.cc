// The mission run's units under their claims (unit_claim.h), as RunMission runs them one after
// the other and `areomap run-unit` runs them one at a time on many hosts: the same code, so a
// unit's products do not depend on who ran it.
#include <cmath>
#include <cstdio>

#include "areomap/landmarks/localization_error.h"
#include "areomap/map/error.h"
#include "areomap/pipeline/work_plan.h"
#include "mission_units.h"

namespace areomap::mission_run {

namespace fs = std::filesystem;
using nlohmann::json;

double SecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

json EnsureUnit(const RunContext& run, const std::string& unit_id, const fs::path& unit_dir,
                const std::function<json()>& compute, bool* reused,
                const std::function<bool(const json&)>& accept) {
  json summary;
  std::string error;
  const UnitOutcome outcome = RunClaimedUnit(
      ClaimFile(run.out_dir, unit_id), unit_dir / "error.txt", unit_id,
      [&] {
        summary = FinishedUnit(run, unit_dir);
        return !summary.is_null() && (!accept || accept(summary));
      },
      [&] {
        summary = compute();
        if (fs::exists(unit_dir)) FinishUnit(run, unit_dir, summary);
      },
      run.claims, /*wait=*/true, &error);
  if (outcome == UnitOutcome::kFailed) throw Error(error);
  if (reused) *reused = outcome == UnitOutcome::kReused;
  return summary;
}

namespace {

std::string Digits(int n) {
  char text[16];
  std::snprintf(text, sizeof(text), "%03d", n);
  return text;
}

}  // namespace

std::string SiteUnitId(int site) { return "site_" + Digits(site); }
std::string LegUnitId(int site_a, int site_b) {
  return "leg_" + Digits(site_a) + "_" + Digits(site_b);
}
std::string SecondPassUnitId(int site_a, int site_b) {
  return LegUnitId(site_a, site_b) + "_pass2";
}

json EnsureSiteUnit(const RunContext& run, size_t site_index, const ProgressCallback& progress,
                    bool* reused) {
  const int site = run.mission->sites[site_index].site;
  return EnsureUnit(
      run, SiteUnitId(site), SiteDir(run, site),
      [&] { return RunSiteUnit(run, site_index, progress); }, reused);
}

namespace {

json MatchLeg(const RunContext& run, size_t index_a, SiteRocksCache& rocks,
              const RockMatchingOptions& matching, const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  json done = RunLegUnit(run, index_a, index_a + 1, rocks, matching, progress);
  done["seconds"] = SecondsSince(start);
  return done;
}

// A leg's first-pass figures: "first_pass" after the second pass matched it again, else the leg.
const json& FirstPass(const json& leg) {
  const auto found = leg.find("first_pass");
  return found != leg.end() && found->is_object() ? *found : leg;
}

// The first-pass figures a leg keeps when the second pass matches it again.
json FirstPassRecord(const json& leg) {
  const json& first = FirstPass(leg);
  json record = json::object();
  for (const char* key :
       {"outcome", "tie_points", "rock_matches", "relative_error_percent", "conformal_chi2",
        "conformal_redundancy", "tie_variance_factor", "seconds"}) {
    if (first.contains(key)) record[key] = first[key];
  }
  return record;
}

}  // namespace

json EnsureLegUnit(const RunContext& run, size_t index_a, SiteRocksCache& rocks,
                   const ProgressCallback& progress, bool* reused) {
  const int site_a = run.mission->sites[index_a].site;
  const int site_b = run.mission->sites[index_a + 1].site;
  return EnsureUnit(
      run, LegUnitId(site_a, site_b), LegDir(run, site_a, site_b),
      [&] {
        for (const int site : {site_a, site_b}) {
          if (FinishedUnit(run, SiteDir(run, site)).is_null()) {
            throw Error(LegUnitId(site_a, site_b) + " needs the site unit " + SiteUnitId(site) +
                        " finished first");
          }
        }
        return MatchLeg(run, index_a, rocks, run.options->matching, progress);
      },
      reused);
}

// The rock tie points' a-posteriori variance factor over the run's legs: their first-pass
// conformal fits' chi2 (recorded at the pass's tie_variance_factor, scaled back to the a-priori
// covariances) and redundancy, pooled (PoolVarianceFactor).
PooledVarianceFactor FirstPassTieVariance(const std::vector<json>& legs) {
  std::vector<SitePairError> fits;
  for (const json& leg : legs) {
    const json& first = FirstPass(leg);
    const json chi2 = first.value("conformal_chi2", json());
    if (!chi2.is_number() || !std::isfinite(chi2.get<double>())) continue;  // null when resumed
    SitePairError fit;
    fit.chi2 = chi2.get<double>() * first.value("tie_variance_factor", 1.0);
    fit.redundancy = first.value("conformal_redundancy", 0);
    fits.push_back(fit);
  }
  return PoolVarianceFactor(fits);
}

// summary.json's "rock_tie_variance": the pooled figures (null when no leg had redundancy) and
// the factor the second pass applied (null when it did not run).
json TieVarianceJson(const PooledVarianceFactor& pooled, std::optional<double> applied) {
  const auto number = [](double v) { return std::isfinite(v) ? json(v) : json(); };
  return {{"legs", pooled.fits},
          {"chi2", pooled.chi2},
          {"redundancy", pooled.redundancy},
          {"sigma0_squared", number(pooled.estimate)},
          {"sigma0_squared_upper_95", number(pooled.upper_95)},
          {"applied_factor", applied ? json(*applied) : json()}};
}

std::optional<double> SecondPassFactor(const RunContext& run, const std::vector<json>& legs) {
  return run.options->RockVariancePassFactor(FirstPassTieVariance(legs));
}

bool EnsureLegSecondPass(const RunContext& run, size_t index_a, SiteRocksCache& rocks,
                         std::optional<double> factor, json& leg,
                         const ProgressCallback& progress) {
  RockMatchingOptions matching = run.options->matching;
  if (factor) matching.tie_variance_factor = *factor;
  const double wanted = matching.tie_variance_factor;
  const auto matched_with_wanted = [wanted](const json& summary) {
    return std::abs(summary.value("tie_variance_factor", 1.0) - wanted) <= 1e-12 * wanted;
  };
  if (matched_with_wanted(leg)) return false;
  const int site_a = run.mission->sites[index_a].site;
  const int site_b = run.mission->sites[index_a + 1].site;
  bool reused = false;
  leg = EnsureUnit(
      run, SecondPassUnitId(site_a, site_b), LegDir(run, site_a, site_b),
      [&] {
        // The first pass as recorded now (another process may have finished it meanwhile).
        const json recorded = FinishedUnit(run, LegDir(run, site_a, site_b));
        if (recorded.is_null()) {
          throw Error(SecondPassUnitId(site_a, site_b) + " needs the leg unit " +
                      LegUnitId(site_a, site_b) + " finished first");
        }
        const json first = FirstPassRecord(recorded);
        json done = MatchLeg(run, index_a, rocks, matching, progress);
        if (factor) {
          done["first_pass"] = first;
          done["seconds"] = done["seconds"].get<double>() + first.value("seconds", 0.0);
        }
        return done;
      },
      &reused, matched_with_wanted);
  return !reused;
}

json EnsureCratersUnit(const RunContext& run, const ProgressCallback& progress, bool* reused) {
  if (!run.options->detect_craters) return nullptr;
  return EnsureUnit(
      run, "craters", run.out_dir / "craters",
      [&] {
        const auto start = std::chrono::steady_clock::now();
        json craters = RunCratersUnit(run, progress);
        craters["seconds"] = SecondsSince(start);
        return craters;
      },
      reused);
}

}  // namespace areomap::mission_run
