// A small JSON Schema validator for the subset the OpenAPI document uses
// (server/src/routes/json_schema.h): type (a name or a list, "integer"
// being a number without a fraction), required, properties, items, enum,
// anyOf, additionalProperties as a schema, and $ref to
// "#/components/schemas/NAME" of the document given. Anything else in a
// schema is ignored (descriptions, format). Independent of the server's
// code on purpose: it checks what the server answers against what the
// server documents.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::testing {

// What in `value` breaks `schema`, one line per violation naming where
// ("/pumps/0/health: ..."); empty when it conforms. `document` resolves
// $ref (the served openapi.json); a $ref it lacks is a violation too.
std::vector<std::string> schema_violations(const nlohmann::json& value, const nlohmann::json& schema,
                                           const nlohmann::json& document);

}  // namespace ambdiag::testing
