#include "areomap/pipeline/work_plan.h"

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>
#include <thread>

#include "areomap/map/atomic_file.h"
#include "areomap/map/error.h"
#include "areomap/map/output_folder.h"

namespace areomap {

namespace fs = std::filesystem;
using nlohmann::json;

size_t WorkPlan::UnitCount() const {
  size_t count = 0;
  for (const PlannedStage& stage : stages) count += stage.units.size();
  return count;
}

const PlannedUnit& WorkPlan::Unit(const std::string& id, const PlannedStage** stage_out) const {
  for (const PlannedStage& stage : stages) {
    for (const PlannedUnit& unit : stage.units) {
      if (unit.id != id) continue;
      if (stage_out) *stage_out = &stage;
      return unit;
    }
  }
  std::string names;
  for (const PlannedStage& stage : stages) {
    names += (names.empty() ? "" : ", ") + stage.name + " (" +
             (stage.units.empty() ? std::string("no units") : stage.units.front().id) +
             (stage.units.size() > 1 ? " ... " + stage.units.back().id : "") + ")";
  }
  throw Error("the plan has no unit \"" + id + "\"; its stages: " + names);
}

const PlannedStage& WorkPlan::Stage(const std::string& name) const {
  std::string names;
  for (const PlannedStage& stage : stages) {
    if (stage.name == name) return stage;
    names += (names.empty() ? "" : ", ") + stage.name;
  }
  throw Error("the plan has no stage \"" + name + "\"; its stages: " + names);
}

json WorkPlan::ToJson() const {
  json stages_json = json::array();
  for (const PlannedStage& stage : stages) {
    json units = json::array();
    for (const PlannedUnit& unit : stage.units) {
      units.push_back({{"id", unit.id},
                       {"folder", unit.folder},
                       {"after", unit.after},
                       {"description", unit.description}});
    }
    json stage_json = {{"name", stage.name}, {"after", stage.after}, {"units", units}};
    if (stage.tolerates_failures) stage_json["tolerates_failures"] = true;
    stages_json.push_back(stage_json);
  }
  return {{"format", "areomap-plan"}, {"version", 1},           {"job", job},
          {"inputs", inputs},         {"arguments", arguments}, {"fingerprint", fingerprint},
          {"stages", stages_json}};
}

namespace {

template <typename T>
T Field(const json& object, const char* key, const std::string& where) {
  try {
    return object.at(key).get<T>();
  } catch (const json::exception&) {
    throw Error(where + ": field \"" + key + "\" is missing or of the wrong type");
  }
}

}  // namespace

WorkPlan WorkPlan::FromJson(const json& plan_json, const std::string& source) {
  if (!plan_json.is_object() || plan_json.value("format", "") != "areomap-plan") {
    throw Error(source + ": not an areomap plan (expected \"format\": \"areomap-plan\")");
  }
  if (plan_json.value("version", 0) != 1) {
    throw Error(source + ": plan version " + plan_json.value("version", json()).dump() +
                " is not supported (expected 1)");
  }
  WorkPlan plan;
  plan.job = Field<std::string>(plan_json, "job", source);
  plan.inputs = Field<std::vector<std::string>>(plan_json, "inputs", source);
  plan.arguments = Field<std::vector<std::string>>(plan_json, "arguments", source);
  plan.fingerprint = Field<std::string>(plan_json, "fingerprint", source);
  const json stages = Field<json>(plan_json, "stages", source);
  if (!stages.is_array()) throw Error(source + ": \"stages\" must be an array");
  std::set<std::string> ids;
  for (size_t s = 0; s < stages.size(); ++s) {
    const std::string where = source + ": stages[" + std::to_string(s) + "]";
    PlannedStage stage;
    stage.name = Field<std::string>(stages[s], "name", where);
    stage.after = Field<std::vector<std::string>>(stages[s], "after", where);
    stage.tolerates_failures = stages[s].value("tolerates_failures", false);
    const json units = Field<json>(stages[s], "units", where);
    if (!units.is_array()) throw Error(where + ": \"units\" must be an array");
    for (size_t u = 0; u < units.size(); ++u) {
      const std::string unit_where = where + ".units[" + std::to_string(u) + "]";
      PlannedUnit unit;
      unit.id = Field<std::string>(units[u], "id", unit_where);
      unit.folder = Field<std::string>(units[u], "folder", unit_where);
      unit.after = Field<std::vector<std::string>>(units[u], "after", unit_where);
      unit.description = units[u].value("description", "");
      if (unit.id.empty() ||
          unit.id.find_first_not_of("abcdefghijklmnopqrstuvwxyz0123456789_") != std::string::npos) {
        throw Error(unit_where + ": unit id \"" + unit.id + "\" must be [a-z0-9_]+");
      }
      if (fs::path(unit.folder).is_absolute() || unit.folder.find("..") != std::string::npos) {
        throw Error(unit_where + ": folder \"" + unit.folder + "\" must lie inside the plan's");
      }
      if (!ids.insert(unit.id).second) {
        throw Error(unit_where + ": unit id \"" + unit.id + "\" appears twice");
      }
      stage.units.push_back(std::move(unit));
    }
    plan.stages.push_back(std::move(stage));
  }
  return plan;
}

void WriteWorkPlan(const fs::path& dir, const WorkPlan& plan) {
  WriteFileAtomically(dir / kPlanFileName, plan.ToJson().dump(2) + "\n");
}

WorkPlan ReadWorkPlan(const fs::path& dir) {
  const fs::path file = dir / kPlanFileName;
  std::ifstream in(file);
  if (!in) {
    throw Error(file.string() +
                ": no plan here; write one with `areomap run MISSION --out DIR --plan` or "
                "`areomap craters IMAGE... --out DIR --plan`");
  }
  const json parsed = json::parse(in, nullptr, false);
  if (parsed.is_discarded()) throw Error(file.string() + ": not valid JSON");
  return WorkPlan::FromJson(parsed, file.string());
}

std::string FilesIdentity(const std::vector<fs::path>& files, const fs::path& root) {
  uint64_t hash = 14695981039346656037ull;
  const auto add = [&hash](const std::string& text) {
    for (const unsigned char c : text) {
      hash ^= c;
      hash *= 1099511628211ull;
    }
  };
  for (const fs::path& file : files) {
    if (file.empty()) continue;
    std::error_code ec;
    const uintmax_t size = fs::file_size(file, ec);
    const auto time = fs::last_write_time(file, ec);
    add((root.empty() ? file : file.lexically_relative(root)).string() + '\n' +
        std::to_string(size) + ' ' + std::to_string(time.time_since_epoch().count()) + '\n');
  }
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

WorkPlan WritePlanInFolder(const fs::path& dir, const WorkPlan& plan,
                           const OutputFolderOptions& policy) {
  const auto same_plan_there = [&] {
    if (!fs::exists(dir / kPlanFileName)) return false;
    try {
      return ReadWorkPlan(dir).ToJson() == plan.ToJson();
    } catch (const Error&) {
      return false;  // Not a plan of this version: the policy decides.
    }
  };
  if (same_plan_there()) return plan;
  try {
    OutputFolder out(dir, policy);
    WriteWorkPlan(out.dir(), plan);
    out.Commit();
    return plan;
  } catch (const Error&) {
    if (!fs::exists(dir / OutputFolder::kLockName)) throw;
    for (int i = 0; i < 50; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(200));
      if (same_plan_there()) return plan;
    }
    throw;
  }
}

fs::path ClaimFile(const fs::path& dir, const std::string& unit_id) {
  return dir / kUnitsFolderName / (unit_id + ".claim");
}

fs::path DoneFile(const fs::path& dir, const std::string& unit_id) {
  return dir / kUnitsFolderName / (unit_id + ".done");
}

fs::path ErrorFile(const fs::path& dir, const PlannedUnit& unit) {
  return (dir / unit.folder / "error.txt").lexically_normal();
}

bool DoneFileMatches(const fs::path& dir, const std::string& unit_id,
                     const std::string& fingerprint) {
  std::ifstream in(DoneFile(dir, unit_id));
  std::stringstream text;
  text << in.rdbuf();
  return in && text.str() == fingerprint + "\n";
}

void WriteDoneFile(const fs::path& dir, const std::string& unit_id,
                   const std::string& fingerprint) {
  fs::create_directories(dir / kUnitsFolderName);
  WriteFileAtomically(DoneFile(dir, unit_id), fingerprint + "\n");
}

}  // namespace areomap
