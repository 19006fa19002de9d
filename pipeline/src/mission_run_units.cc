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

SiteUnitResult EnsureSiteUnit(const RunContext& run, size_t site_index,
                              const ProgressCallback& progress, bool* reused) {
  const int site = run.mission->sites[site_index].site;
  return EnsureUnit<SiteUnitResult>(
      run, SiteUnitId(site), SiteDir(run, site),
      [&] { return RegisterSite(run, site_index, progress); }, reused);
}

namespace {

// MatchLeg with the sites' rocks from `rocks`.
LegUnitResult MatchLegWith(const MissionRunContext& run, size_t index_a, SiteRocksCache& rocks,
                           const RockMatchingOptions& matching, const ProgressCallback& progress) {
  const auto start = std::chrono::steady_clock::now();
  LegUnitResult done = RunLegUnit(run, index_a, index_a + 1, rocks, matching, progress);
  done.match.seconds = SecondsSince(start);
  return done;
}

// A leg's first-pass figures: its first_pass after the second pass matched it again, else its
// own.
const LegPassRecord& FirstPass(const LegUnitResult& leg) {
  return leg.first_pass ? *leg.first_pass : leg.match;
}

}  // namespace

LegUnitResult MatchLeg(const MissionRunContext& run, size_t index_a,
                       const RockMatchingOptions& matching, const ProgressCallback& progress) {
  SiteRocksCache rocks(run);
  return MatchLegWith(run, index_a, rocks, matching, progress);
}

LegUnitResult EnsureLegUnit(const RunContext& run, size_t index_a, SiteRocksCache& rocks,
                            const ProgressCallback& progress, bool* reused) {
  const int site_a = run.mission->sites[index_a].site;
  const int site_b = run.mission->sites[index_a + 1].site;
  return EnsureUnit<LegUnitResult>(
      run, LegUnitId(site_a, site_b), LegDir(run, site_a, site_b),
      [&] {
        for (const int site : {site_a, site_b}) {
          if (FinishedUnit(run, SiteDir(run, site)).is_null()) {
            throw Error(LegUnitId(site_a, site_b) + " needs the site unit " + SiteUnitId(site) +
                        " finished first");
          }
        }
        return MatchLegWith(run, index_a, rocks, run.options->matching, progress);
      },
      reused);
}

// The rock tie points' a-posteriori variance factor over the run's legs: their first-pass
// conformal fits' chi2 (recorded at the pass's tie_variance_factor, scaled back to the a-priori
// covariances) and redundancy, pooled (PoolVarianceFactor).
PooledVarianceFactor FirstPassTieVariance(const std::vector<LegUnitResult>& legs) {
  std::vector<SitePairError> fits;
  for (const LegUnitResult& leg : legs) {
    const LegPassRecord& first = FirstPass(leg);
    if (!first.conformal_chi2 || !std::isfinite(*first.conformal_chi2)) continue;  // null: resumed
    SitePairError fit;
    fit.chi2 = *first.conformal_chi2 * first.tie_variance_factor;
    fit.redundancy = static_cast<int>(first.conformal_redundancy.value_or(0));
    fits.push_back(fit);
  }
  return PoolVarianceFactor(fits);
}

// summary.json's "rock_tie_variance": the pooled figures (null when no leg had redundancy) and
// the factor the second pass applied (null when it did not run).
TieVarianceRecord TieVariance(const PooledVarianceFactor& pooled, std::optional<double> applied) {
  const auto number = [](double v) { return std::isfinite(v) ? Figure(v) : std::nullopt; };
  return {
      pooled.fits, pooled.redundancy, pooled.chi2, number(pooled.estimate), number(pooled.upper_95),
      applied};
}

std::optional<double> SecondPassFactor(const RunContext& run,
                                       const std::vector<LegUnitResult>& legs) {
  return run.options->RockVariancePassFactor(FirstPassTieVariance(legs));
}

bool EnsureLegSecondPass(const RunContext& run, size_t index_a, SiteRocksCache& rocks,
                         std::optional<double> factor, LegUnitResult& leg,
                         const ProgressCallback& progress) {
  RockMatchingOptions matching = run.options->matching;
  if (factor) matching.tie_variance_factor = *factor;
  const double wanted = matching.tie_variance_factor;
  const auto matched_with_wanted = [wanted](const LegUnitResult& summary) {
    return std::abs(summary.match.tie_variance_factor - wanted) <= 1e-12 * wanted;
  };
  if (matched_with_wanted(leg)) return false;
  const int site_a = run.mission->sites[index_a].site;
  const int site_b = run.mission->sites[index_a + 1].site;
  bool reused = false;
  leg = EnsureUnit<LegUnitResult>(
      run, SecondPassUnitId(site_a, site_b), LegDir(run, site_a, site_b),
      [&] {
        // The first pass as recorded now (another process may have finished it meanwhile).
        const std::optional<LegUnitResult> recorded =
            FinishedUnitResult<LegUnitResult>(run, LegDir(run, site_a, site_b));
        if (!recorded) {
          throw Error(SecondPassUnitId(site_a, site_b) + " needs the leg unit " +
                      LegUnitId(site_a, site_b) + " finished first");
        }
        const LegPassRecord first = FirstPass(*recorded);
        LegUnitResult done = MatchLegWith(run, index_a, rocks, matching, progress);
        if (factor) {
          done.first_pass = first;
          done.match.seconds = done.match.seconds.value_or(0.0) + first.seconds.value_or(0.0);
        }
        return done;
      },
      &reused, matched_with_wanted);
  return !reused;
}

std::optional<CratersUnitResult> EnsureCratersUnit(const RunContext& run,
                                                   const ProgressCallback& progress, bool* reused) {
  if (!run.options->detect_craters) return std::nullopt;
  return EnsureUnit<CratersUnitResult>(
      run, "craters", run.out_dir / "craters",
      [&] {
        const auto start = std::chrono::steady_clock::now();
        CratersUnitResult craters = DetectOrbitalCraters(run, progress);
        craters.seconds = SecondsSince(start);
        return craters;
      },
      reused);
}

}  // namespace areomap::mission_run
