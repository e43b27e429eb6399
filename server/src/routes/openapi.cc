#include "routes/openapi.h"

#include <cctype>
#include <set>
#include <stdexcept>

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

struct ErrorResponse {
  int status;
  const char* name;
  const char* description;
};

// rest.md's errors, each with the {"error"} body.
constexpr ErrorResponse kErrors[] = {
    {400, "BadRequest", "a bad request: the message names the field, parameter or encoding"},
    {401, "Unauthorized", "no token, or an unknown or revoked one"},
    {403, "Forbidden", "the token's role is too low: the message names the role needed"},
    {404, "NotFound", "no such resource (unknown pump, run, job, alarm or path)"},
    {410, "Gone", "the data was dropped by the pump's retention policy: the message names the run and when"},
    {409, "Conflict", "the state does not allow the request"},
    {413, "PayloadTooLarge", "the body is larger than the server accepts (8 MiB by default)"},
    {429, "TooManyRequests",
     "the token's (or, without one, the address') request rate is over the limit; Retry-After says when to "
     "retry"},
    {500, "ServerError", "a server fault"},
    {503, "Unavailable",
     "not served now: a write on a server without the analysis service, or too many event streams open"},
};

json error_ref(int status) {
  for (const auto& e : kErrors)
    if (e.status == status) return {{"$ref", std::string("#/components/responses/") + e.name}};
  return json::object();
}

json components(const RouteTable& table) {
  json responses = json::object();
  const json error_content = {{"application/json", {{"schema", {{"$ref", "#/components/schemas/Error"}}}}}};
  for (const auto& e : kErrors) {
    json r = {{"description", e.description}, {"content", error_content}};
    if (e.status == 429)
      r["headers"] = {
          {"Retry-After",
           {{"description", "seconds until a request is allowed again"}, {"schema", {{"type", "integer"}}}}}};
    if (e.status == 401)
      r["headers"] = {{"WWW-Authenticate", {{"description", "Bearer"}, {"schema", {{"type", "string"}}}}}};
    responses[e.name] = r;
  }
  json schemas = {{"Error",
             {{"type", "object"},
              {"required", {"error"}},
              {"properties",
               {{"error",
                 {{"type", "string"},
                  {"description", "what is wrong, naming the field, parameter or state"}}}}}}}};
  for (const auto& [name, s] : table.schemas()) {
    if (schemas.contains(name)) throw std::logic_error("schema name taken: " + name);
    schemas[name] = s;
  }
  return {{"schemas", schemas},
          {"responses", responses},
          {"securitySchemes",
           {{"bearer",
             {{"type", "http"},
              {"scheme", "bearer"},
              {"description",
               "a token from `ambdiag token add` (only its hash is stored); its role: viewer < operator < "
               "engineer < admin"}}},
            {"access_token",
             {{"type", "apiKey"},
              {"in", "query"},
              {"name", "access_token"},
              {"description",
               "the same token as ?access_token=, only on the routes that say so (a browser's EventSource "
               "cannot set headers)"}}}}}};
}

std::string operation_id(const std::string& method, const std::string& pattern,
                         std::set<std::string>& taken) {
  std::string id;
  for (const char c : method) id += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  for (const char c : pattern) {
    const bool word = std::isalnum(static_cast<unsigned char>(c)) != 0;
    if (word)
      id += c;
    else if (id.back() != '_')
      id += '_';
  }
  while (id.back() == '_') id.pop_back();
  std::string unique = id;
  for (int n = 2; !taken.insert(unique).second; ++n) unique = id + "_" + std::to_string(n);
  return unique;
}

// The route's schema where it has one, else what the content type says.
json content_schema(const std::string& type, const json& schema) {
  if (!schema.is_null()) return schema;
  if (type == "application/json") return {{"type", "object"}};
  return {{"type", "string"}};
}

// Every $ref names a component: a typo in a schema is a programming error
// that every test requesting the document catches.
void check_refs(const json& j, const json& schemas) {
  if (j.is_object()) {
    if (const auto r = j.find("$ref"); r != j.end() && r->is_string()) {
      const std::string ref = *r;
      const std::string prefix = "#/components/schemas/";  // not the shared responses' refs
      if (ref.rfind(prefix, 0) == 0 && !schemas.contains(ref.substr(prefix.size())))
        throw std::logic_error("no schema for $ref " + ref);
    }
  }
  if (j.is_structured())
    for (const auto& v : j) check_refs(v, schemas);
}

json operation(const Route& r, const std::vector<PatternSegment>& pattern, bool anonymous_read,
               std::set<std::string>& ids) {
  const std::string role = r.role ? storage::to_string(*r.role) : "none";
  std::string description = r.summary + ".";
  if (!r.description.empty()) description += " " + r.description;
  description += r.role ? " Role: " + role + " or higher." : " No token needed.";
  if (r.method == "GET") description += " HEAD answers too.";
  json op = {{"operationId", operation_id(r.method, r.pattern, ids)},
             {"summary", r.summary},
             {"description", description},
             {"x-ambdiag-role", role}};

  json params = json::array();
  for (const auto& s : pattern) {
    if (!s.param) continue;
    params.push_back(
        {{"name", s.text},
         {"in", "path"},
         {"required", true},
         {"schema", {{"type", "string"}}},
         {"description", s.rest ? "URL-encoded ('/' as %2F, ':' as %3A); an unencoded '/' is accepted too"
                                : "URL-encoded path segment"}});
  }
  for (const auto& q : r.query) {
    json p = {{"name", q.name}, {"in", "query"}, {"required", q.required}, {"description", q.description}};
    if (q.repeated) {
      p["schema"] = {{"type", "array"}, {"items", {{"type", "string"}}}};
      p["style"] = "form";
      p["explode"] = true;
    } else {
      p["schema"] = {{"type", "string"}};
    }
    params.push_back(p);
  }
  if (!params.empty()) op["parameters"] = params;

  // A body whose schema requires no key may be left out (ack's {"comment"?}).
  if (!r.body.empty() || !r.body_schema.is_null())
    op["requestBody"] = {{"required", r.body_schema.is_null() || r.body_schema.contains("required")},
                         {"description", r.body.empty() ? "a JSON object" : r.body},
                         {"content", {{r.body_type, {{"schema", content_schema(r.body_type, r.body_schema)}}}}}};

  json responses = {{std::to_string(r.status),
                     {{"description", r.summary},
                      {"content", {{r.response_type, {{"schema", content_schema(r.response_type, r.response_schema)}}}}}}}};
  std::vector<int> errors = {400, 404, 500};
  if (r.role) errors.insert(errors.end(), {401, 403, 429});
  if (r.method != "GET")
    errors.insert(errors.end(), {409, 413, 503});
  else if (r.token_in_query)
    errors.push_back(503);
  errors.insert(errors.end(), r.errors.begin(), r.errors.end());
  for (const int e : errors) responses[std::to_string(e)] = error_ref(e);
  op["responses"] = responses;

  if (!r.role) {
    op["security"] = json::array();  // open: no token
  } else {
    json sec = json::array({{{"bearer", json::array()}}});
    if (r.token_in_query) sec.push_back({{"access_token", json::array()}});
    if (anonymous_read && *r.role == storage::Role::viewer)
      sec.push_back(json::object());  // --anonymous-read
    op["security"] = sec;
  }
  return op;
}

std::string openapi_path(const std::vector<PatternSegment>& pattern) {
  std::string p;
  for (const auto& s : pattern) p += "/" + (s.param ? "{" + s.text + "}" : s.text);
  return p;
}

}  // namespace

json openapi_document(const RouteTable& table, bool anonymous_read) {
  json paths = json::object();
  std::set<std::string> ids;
  for (size_t i = 0; i < table.routes().size(); ++i) {
    const Route& r = table.routes()[i];
    std::string method;
    for (const char c : r.method) method += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    paths[openapi_path(table.pattern(i))][method] = operation(r, table.pattern(i), anonymous_read, ids);
  }
  json comps = components(table);
  check_refs(paths, comps["schemas"]);
  check_refs(comps["schemas"], comps["schemas"]);
  return {{"openapi", "3.1.0"},
          {"info",
           {{"title", "ambdiag"},
            {"version", "0.1.0"},
            {"summary",
             "model-based fault diagnosis of pumps in active magnetic bearings: runs, analyses, jobs, "
             "trends, alarms"},
            {"description",
             "Generated from the server's route table, so it lists every route this server answers. Errors "
             "are the status "
             "and {\"error\": \"message\"}. Every request but the open routes (x-ambdiag-role: none) needs "
             "`Authorization: Bearer TOKEN` with at least the route's role (x-ambdiag-role); roles: viewer < "
             "operator < "
             "engineer < admin. Times are ISO 8601 UTC."}}},
          {"security", json::array({{{"bearer", json::array()}}})},
          {"paths", paths},
          {"components", comps}};
}

}  // namespace ambdiag::server::detail
