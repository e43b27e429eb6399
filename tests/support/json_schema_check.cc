#include "json_schema_check.h"

#include <algorithm>
#include <cmath>

namespace ambdiag::testing {

namespace {

using nlohmann::json;

bool has_type(const json& v, const std::string& type) {
  if (type == "object") return v.is_object();
  if (type == "array") return v.is_array();
  if (type == "string") return v.is_string();
  if (type == "boolean") return v.is_boolean();
  if (type == "null") return v.is_null();
  if (type == "number") return v.is_number();
  if (type == "integer")
    return v.is_number_integer() || (v.is_number_float() && std::trunc(v.get<double>()) == v.get<double>());
  return false;
}

class Checker {
 public:
  explicit Checker(const json& document) : document_(document) {}

  void check(const json& v, const json& s, const std::string& at, int depth = 0) {
    if (depth > 64) return fail(at, "schema nests too deep (a $ref cycle?)");
    if (!s.is_object()) return;
    if (s.contains("$ref")) {
      const std::string ref = s["$ref"].get<std::string>();
      const std::string prefix = "#/components/schemas/";
      const json* target = nullptr;
      const json::json_pointer schemas("/components/schemas");
      if (ref.rfind(prefix, 0) == 0 && document_.contains(schemas)) {
        const json& all = document_.at(schemas);
        if (const auto it = all.find(ref.substr(prefix.size())); it != all.end()) target = &*it;
      }
      if (!target) return fail(at, "unresolved $ref " + ref);
      check(v, *target, at, depth + 1);
    }
    if (s.contains("type") && !type_ok(v, s["type"])) return fail(at, "is " + std::string(v.type_name()) + ", not " + s["type"].dump());
    if (s.contains("enum") && std::find(s["enum"].begin(), s["enum"].end(), v) == s["enum"].end())
      fail(at, v.dump() + " is not one of " + s["enum"].dump());
    if (s.contains("anyOf")) check_any_of(v, s["anyOf"], at, depth);
    if (v.is_object()) check_object(v, s, at, depth);
    if (v.is_array() && s.contains("items"))
      for (size_t i = 0; i < v.size(); ++i) check(v[i], s["items"], at + "/" + std::to_string(i), depth + 1);
  }

  std::vector<std::string> violations;

 private:
  static bool type_ok(const json& v, const json& type) {
    if (type.is_string()) return has_type(v, type.get<std::string>());
    for (const auto& t : type)
      if (has_type(v, t.get<std::string>())) return true;
    return false;
  }

  void check_any_of(const json& v, const json& alternatives, const std::string& at, int depth) {
    for (const auto& alt : alternatives) {
      Checker c(document_);
      c.check(v, alt, at, depth + 1);
      if (c.violations.empty()) return;
    }
    fail(at, "matches none of anyOf " + alternatives.dump());
  }

  void check_object(const json& v, const json& s, const std::string& at, int depth) {
    for (const auto& key : s.value("required", json::array()))
      if (!v.contains(key.get<std::string>())) fail(at, "lacks required key \"" + key.get<std::string>() + "\"");
    const json props = s.value("properties", json::object());
    for (const auto& [key, value] : v.items()) {
      const std::string where = at + "/" + key;
      if (props.contains(key))
        check(value, props[key], where, depth + 1);
      else if (s.contains("additionalProperties"))
        check(value, s["additionalProperties"], where, depth + 1);
    }
  }

  void fail(const std::string& at, const std::string& what) { violations.push_back((at.empty() ? "/" : at) + ": " + what); }

  const json& document_;
};

}  // namespace

std::vector<std::string> schema_violations(const json& value, const json& schema, const json& document) {
  Checker c(document);
  c.check(value, schema, "");
  return c.violations;
}

}  // namespace ambdiag::testing
