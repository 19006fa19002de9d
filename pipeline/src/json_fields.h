// Private to areomap::pipeline: reading the run's JSON records (summary.json, unit.json) into
// typed structs with errors that name the field's path, and writing optional figures back.
//
// Failure: a field of another type throws areomap::Error naming its place, e.g.
// "summary.json: sites[2].registration.correlation is \"x\"; expected a number (the type areomap
// run writes)". A missing or null field takes the caller's fallback: records written before the
// field existed stay readable.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "areomap/map/error.h"

namespace areomap::json_fields {

// One JSON object of a record being read, with its place for error messages
// ("summary.json: legs[2].faults").
class Fields {
 public:
  using json = nlohmann::json;

  Fields(const json& object, std::string where) : object_(object), where_(std::move(where)) {}
  // `value` as the record's top object; throws naming `where` when it is not an object.
  static Fields Top(const json& value, const std::string& where) {
    if (!value.is_object()) {
      throw Error(where + " is " + value.dump().substr(0, 40) + "; expected an object");
    }
    return Fields(value, where);
  }

  const json& object() const { return object_; }
  const std::string& where() const { return where_; }
  // Present and not null.
  bool Has(const char* key) const {
    const auto it = object_.find(key);
    return it != object_.end() && !it->is_null();
  }
  std::optional<double> Number(const char* key) const {
    if (!Has(key)) return std::nullopt;
    const json& v = object_.at(key);
    if (!v.is_number()) Fail(key, v, "a number");
    return v.get<double>();
  }
  // A figure as recorded: nullopt when missing, NaN when null (the writer's non-finite number).
  std::optional<double> Recorded(const char* key) const {
    const auto it = object_.find(key);
    if (it == object_.end()) return std::nullopt;
    if (it->is_null()) return std::numeric_limits<double>::quiet_NaN();
    if (!it->is_number()) Fail(key, *it, "a number");
    return it->get<double>();
  }
  // A number that the writer records as null when it is not finite: NaN when missing or null.
  double Real(const char* key) const {
    return Number(key).value_or(std::numeric_limits<double>::quiet_NaN());
  }
  double Real(const char* key, double fallback) const { return Number(key).value_or(fallback); }
  std::optional<int64_t> OptionalCount(const char* key) const {
    if (!Has(key)) return std::nullopt;
    const json& v = object_.at(key);
    if (!v.is_number_integer()) Fail(key, v, "an integer");
    return v.get<int64_t>();
  }
  int64_t Count(const char* key, int64_t fallback) const {
    return OptionalCount(key).value_or(fallback);
  }
  int Integer(const char* key, int fallback) const {
    return static_cast<int>(Count(key, fallback));
  }
  bool Flag(const char* key, bool fallback) const {
    if (!Has(key)) return fallback;
    const json& v = object_.at(key);
    if (!v.is_boolean()) Fail(key, v, "true or false");
    return v.get<bool>();
  }
  std::string Text(const char* key, const std::string& fallback) const {
    if (!Has(key)) return fallback;
    const json& v = object_.at(key);
    if (!v.is_string()) Fail(key, v, "a string");
    return v.get<std::string>();
  }
  // The object at `key`; nullopt when absent or null (a stage that was off).
  std::optional<Fields> Object(const char* key) const {
    if (!Has(key)) return std::nullopt;
    const json& v = object_.at(key);
    if (!v.is_object()) Fail(key, v, "an object");
    return Fields(v, Where(key));
  }
  // The value at `key` as recorded (null when absent): a record another module owns.
  json Raw(const char* key) const {
    const auto it = object_.find(key);
    return it == object_.end() ? json() : *it;
  }
  // The elements of the array at `key` (none when absent).
  const json& Array(const char* key) const {
    static const json kEmpty = json::array();
    if (!Has(key)) return kEmpty;
    const json& v = object_.at(key);
    if (!v.is_array()) Fail(key, v, "an array");
    return v;
  }
  std::vector<int> Integers(const char* key) const {
    std::vector<int> out;
    const json& array = Array(key);
    for (size_t i = 0; i < array.size(); ++i) {
      if (!array[i].is_number_integer()) Fail(key, array[i], "an array of integers");
      out.push_back(array[i].get<int>());
    }
    return out;
  }
  // Array elements that are numbers; a null element (a figure that was not finite) is NaN.
  std::vector<double> Numbers(const char* key) const {
    std::vector<double> out;
    const json& array = Array(key);
    for (size_t i = 0; i < array.size(); ++i) {
      if (array[i].is_null()) {
        out.push_back(std::numeric_limits<double>::quiet_NaN());
        continue;
      }
      if (!array[i].is_number()) Fail(key, array[i], "an array of numbers");
      out.push_back(array[i].get<double>());
    }
    return out;
  }
  std::vector<std::string> Texts(const char* key) const {
    std::vector<std::string> out;
    const json& array = Array(key);
    for (size_t i = 0; i < array.size(); ++i) {
      if (!array[i].is_string()) Fail(key, array[i], "an array of strings");
      out.push_back(array[i].get<std::string>());
    }
    return out;
  }
  // Element `i` of the array at `key`, which must be an object.
  Fields Element(const char* key, size_t i) const {
    const json& e = Array(key)[i];
    const std::string where = Where(key) + "[" + std::to_string(i) + "]";
    if (!e.is_object()) {
      throw Error(where + " is " + e.dump().substr(0, 40) + "; expected an object");
    }
    return Fields(e, where);
  }
  std::string Where(const char* key) const { return where_ + "." + key; }
  [[noreturn]] void Fail(const char* key, const json& value, const char* expected) const {
    throw Error(Where(key) + " is " + value.dump().substr(0, 40) + "; expected " + expected +
                " (the type areomap run writes)");
  }

 private:
  const json& object_;
  std::string where_;
};

// `value` under `key` unless nullopt.
template <typename T>
void Put(nlohmann::json& object, const char* key, const std::optional<T>& value) {
  if (value) object[key] = *value;
}

// `object` without the keys a struct reads into typed fields.
inline nlohmann::json Others(const nlohmann::json& object,
                             std::initializer_list<const char*> typed) {
  nlohmann::json rest = object;
  for (const char* key : typed) rest.erase(key);
  return rest;
}

}  // namespace areomap::json_fields
