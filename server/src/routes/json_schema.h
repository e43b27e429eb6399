// Builders of the JSON Schemas (2020-12, as OpenAPI 3.1 uses them) that
// describe what a route answers (Route::response_schema) and takes
// (Route::body_schema) in GET /api/v1/openapi.json. Only the subset the
// document uses: type, required, properties, items, enum, anyOf, $ref to
// a named component (RouteTable::add_schema), additionalProperties as a
// schema (a map). Objects never set additionalProperties false: rest.md
// welcomes more keys.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::server::detail::schema {

using nlohmann::json;
using Props = std::vector<std::pair<std::string, json>>;

json string();
json time();  // ISO 8601 UTC
json integer();
json number();
json boolean();
json any();  // no constraint (a job's result, a run's header)
json one_of(const std::vector<std::string>& values);  // a string from the list
json array(json items);
json map_of(json values);  // an object whose every value is `values` (name -> URL)
json ref(const std::string& component);
json any_of(std::vector<json> alternatives);
// May also be null: the type gains "null" (and an enum null), a $ref
// becomes anyOf [it, null].
json nullable(json s);
// `required`: the keys always there (rest.md's, not marked `?`);
// `optional`: keys that may be absent.
json object(const Props& required, const Props& optional = {});

// The shared enums of rest.md.
json health();      // ok | warning | alarm | unknown
json job_status();  // queued | running | done | failed | cancelled
json alarm_state();  // the ISA-18.2 states
json role();        // viewer | operator | engineer | admin

}  // namespace ambdiag::server::detail::schema
