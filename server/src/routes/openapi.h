// The OpenAPI 3.1 document of every route in the table (GET
// /api/v1/openapi.json; docs/service.md "OpenAPI"): generated, never
// written by hand, so a route cannot be served and undocumented.
#pragma once

#include <nlohmann/json.hpp>

#include "routes/route_table.h"

namespace ambdiag::server::detail {

// `anonymous_read`: this server lets requests without a token read as
// viewer, so viewer routes list "no token" as an alternative.
nlohmann::json openapi_document(const RouteTable& table, bool anonymous_read);

}  // namespace ambdiag::server::detail
