#include "routes/json_schema.h"

#include "alarms/alarm_state.h"

namespace ambdiag::server::detail::schema {

json string() { return {{"type", "string"}}; }
json time() { return {{"type", "string"}, {"description", "ISO 8601 UTC"}}; }
json integer() { return {{"type", "integer"}}; }
json number() { return {{"type", "number"}}; }
json boolean() { return {{"type", "boolean"}}; }
json any() { return json::object(); }

json one_of(const std::vector<std::string>& values) { return {{"type", "string"}, {"enum", values}}; }

json array(json items) { return {{"type", "array"}, {"items", std::move(items)}}; }

json map_of(json values) { return {{"type", "object"}, {"additionalProperties", std::move(values)}}; }

json ref(const std::string& component) { return {{"$ref", "#/components/schemas/" + component}}; }

json any_of(std::vector<json> alternatives) { return {{"anyOf", std::move(alternatives)}}; }

json nullable(json s) {
  if (!s.contains("type")) return any_of({std::move(s), {{"type", "null"}}});
  if (s["type"].is_string()) s["type"] = json::array({s["type"], "null"});
  if (s.contains("enum")) s["enum"].push_back(nullptr);
  return s;
}

json object(const Props& required, const Props& optional) {
  json props = json::object();
  json names = json::array();
  for (const auto& [name, s] : required) {
    props[name] = s;
    names.push_back(name);
  }
  for (const auto& [name, s] : optional) props[name] = s;
  json o = {{"type", "object"}, {"properties", props}};
  if (!names.empty()) o["required"] = names;
  return o;
}

json health() { return one_of({"ok", "warning", "alarm", "unknown"}); }
json job_status() { return one_of({"queued", "running", "done", "failed", "cancelled"}); }
json alarm_state() {
  return one_of(alarm_states());
}
json role() { return one_of({"viewer", "operator", "engineer", "admin"}); }

}  // namespace ambdiag::server::detail::schema
