// summary.json of `areomap run`, typed: what RunMission writes and its readers (the HTML report,
// the CLI's closing lines, scripts through docs/summary-format.md) take from it. The records are
// the units' result structs (unit_results.h), one definition per record: RunSummary::ToJson is
// what the run writes and RunSummary::FromJson the one place that reads it back, so the schema
// lives there and in docs/summary-format.md instead of in string keys spread over the readers.
//
// Units are in the field names (_m metres, _m2 square metres, _deg degrees, _px orbital pixels,
// _percent per cent). A figure a run may lack (no truth, no orbital DTM, craters or products off,
// a leg without tie points) is std::nullopt or NaN as unit_results.h says (Known() for both).
//
// Failure: FromJson throws areomap::Error naming `source` and the field (e.g.
// "summary.json:.sites[2].registration.correlation is \"x\"; expected a number") when a field
// has another type than RunMission writes, or "sites" / "legs" is not an array of objects. A
// missing field takes its record's default (unit_results.h), so older summaries stay readable.
#pragma once

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/pipeline/unit_results.h"

namespace areomap {

// A figure that may be missing.
using OptionalNumber = std::optional<double>;

// Which units this invocation computed and which it found finished.
struct UnitsSummary {
  int sites_computed = 0, sites_reused = 0, legs_computed = 0, legs_reused = 0;
  int legs_rematched = 0;
  // The whole-run units: "computed", "reused" or "off" (empty in older summaries).
  std::string craters, products;
  bool operator==(const UnitsSummary&) const = default;
};

// The records are the units' results (unit_results.h), as the run hands them over; a record an
// older summary lacks, or a stage that was off (null), is std::nullopt.
struct RunSummary {
  std::string mission;                 // The mission folder.
  std::string name;                    // The mission's.
  std::optional<std::string> command;  // "run" when written by RunMissionFolder.
  OptionalNumber seconds;              // Wall time of the invocation.
  std::vector<mission_run::SiteUnitResult> sites;
  std::vector<mission_run::LegUnitResult> legs;
  std::optional<mission_run::TieVarianceRecord> tie_variance;  // "rock_tie_variance".
  std::optional<mission_run::CratersUnitResult> craters;       // null when craters are off.
  std::optional<mission_run::AdjustmentResult> adjustment;
  std::optional<mission_run::GuidedPassesResult> guided;    // "guided_registration".
  std::optional<mission_run::ProductsUnitResult> products;  // null when products are off.
  std::optional<UnitsSummary> units;
  // Wall time per stage [s]: of this invocation, and as recorded when the units were computed.
  std::map<std::string, double> stage_seconds, computed_seconds;
  bool operator==(const RunSummary&) const = default;

  // `source` names the file in error messages.
  static RunSummary FromJson(const nlohmann::json& json, const std::string& source);
  // The fields above under summary.json's names, as RunMission writes them ("craters" and
  // "products" null when nullopt, other nullopt records left out): FromJson of it gives this
  // summary back.
  nlohmann::json ToJson() const;
};

// out_dir/summary.json read by RunSummary::FromJson; throws areomap::Error naming the folder
// when there is none, or the file when it is not JSON or not a run's (no "sites" and "legs").
RunSummary ReadRunSummary(const std::filesystem::path& out_dir);

}  // namespace areomap
