#include "areomap/pipeline/run_summary.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "areomap/map/error.h"
#include "json_fields.h"

namespace areomap {
namespace {

using nlohmann::json;

using json_fields::Fields;
using json_fields::Put;

// The record at `key` read by its result's FromJson; nullopt when absent or null.
template <typename Record>
std::optional<Record> ReadRecord(const Fields& f, const char* key) {
  const std::optional<Fields> record = f.Object(key);
  if (!record) return std::nullopt;
  return Record::FromJson(record->object(), record->where());
}

// Each element of the array at `key` (checked to be objects) read by its result's FromJson.
template <typename Record>
std::vector<Record> ReadRecords(const Fields& f, const char* key) {
  std::vector<Record> out;
  for (size_t i = 0; i < f.Array(key).size(); ++i) {
    const Fields element = f.Element(key, i);
    out.push_back(Record::FromJson(element.object(), element.where()));
  }
  return out;
}

std::map<std::string, double> ReadSeconds(const Fields& f, const char* key) {
  std::map<std::string, double> out;
  if (const std::optional<Fields> seconds = f.Object(key)) {
    for (const auto& [stage, value] : seconds->object().items()) {
      if (const OptionalNumber v = seconds->Number(stage.c_str())) out[stage] = *v;
    }
  }
  return out;
}

template <typename Record>
json Records(const std::vector<Record>& records) {
  json out = json::array();
  for (const Record& r : records) out.push_back(r.ToJson());
  return out;
}

}  // namespace

RunSummary RunSummary::FromJson(const json& json_in, const std::string& source) {
  if (!json_in.is_object() || !json_in.contains("sites") || !json_in.contains("legs")) {
    throw Error(source + ": not the summary of areomap run (expected \"sites\" and \"legs\")");
  }
  for (const char* key : {"sites", "legs"}) {
    const json& list = json_in.at(key);
    if (!list.is_array() ||
        !std::all_of(list.begin(), list.end(), [](const json& e) { return e.is_object(); })) {
      throw Error(source + ": \"" + key + "\" is " + list.dump().substr(0, 40) +
                  "; expected an array of objects (areomap run's)");
    }
  }
  const Fields f(json_in, source + ":");
  RunSummary s;
  s.mission = f.Text("mission", "");
  s.name = f.Text("name", "");
  if (f.Has("command")) s.command = f.Text("command", "");
  s.seconds = f.Number("seconds");
  s.sites = ReadRecords<mission_run::SiteUnitResult>(f, "sites");
  s.legs = ReadRecords<mission_run::LegUnitResult>(f, "legs");
  s.tie_variance = ReadRecord<mission_run::TieVarianceRecord>(f, "rock_tie_variance");
  s.craters = ReadRecord<mission_run::CratersUnitResult>(f, "craters");
  s.adjustment = ReadRecord<mission_run::AdjustmentResult>(f, "adjustment");
  s.guided = ReadRecord<mission_run::GuidedPassesResult>(f, "guided_registration");
  s.products = ReadRecord<mission_run::ProductsUnitResult>(f, "products");
  if (const std::optional<Fields> u = f.Object("units")) {
    s.units = UnitsSummary{u->Integer("sites_computed", 0), u->Integer("sites_reused", 0),
                           u->Integer("legs_computed", 0),  u->Integer("legs_reused", 0),
                           u->Integer("legs_rematched", 0), u->Text("craters", ""),
                           u->Text("products", "")};
  }
  s.stage_seconds = ReadSeconds(f, "stage_seconds");
  s.computed_seconds = ReadSeconds(f, "computed_seconds");
  return s;
}

json RunSummary::ToJson() const {
  json j = {{"mission", mission},
            {"name", name},
            {"sites", Records(sites)},
            {"legs", Records(legs)},
            {"craters", craters ? craters->ToJson() : json()},
            {"products", products ? products->ToJson() : json()},
            {"stage_seconds", stage_seconds},
            {"computed_seconds", computed_seconds}};
  Put(j, "command", command);
  Put(j, "seconds", seconds);
  if (tie_variance) j["rock_tie_variance"] = tie_variance->ToJson();
  if (adjustment) j["adjustment"] = adjustment->ToJson();
  if (guided) j["guided_registration"] = guided->ToJson();
  if (units) {
    j["units"] = {{"sites_computed", units->sites_computed},
                  {"sites_reused", units->sites_reused},
                  {"legs_computed", units->legs_computed},
                  {"legs_reused", units->legs_reused},
                  {"legs_rematched", units->legs_rematched}};
    if (!units->craters.empty()) j["units"]["craters"] = units->craters;
    if (!units->products.empty()) j["units"]["products"] = units->products;
  }
  return j;
}

RunSummary ReadRunSummary(const std::filesystem::path& out_dir) {
  const std::filesystem::path path = out_dir / "summary.json";
  std::ifstream in(path);
  if (!in)
    throw Error(out_dir.string() + ": no summary.json; expected the --out folder of areomap run");
  const json summary = json::parse(in, nullptr, false);
  if (summary.is_discarded()) {
    throw Error(path.string() +
                ": not the summary of areomap run (expected \"sites\" and \"legs\")");
  }
  return RunSummary::FromJson(summary, path.string());
}

}  // namespace areomap
