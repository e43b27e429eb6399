// The service's own routes (rest.md "Service"; docs/service.md "OpenAPI",
// "Metrics", "Live updates"): GET /api/v1/openapi.json, GET /metrics and
// GET /api/v1/events (server-sent events).
#pragma once

#include <atomic>
#include <mutex>
#include <string>

#include "ambdiag/server/events.h"
#include "ambdiag/server/metrics.h"
#include "routes/route_table.h"

namespace ambdiag::server::detail {

// What these routes share with the server; lives as long as it.
struct ServiceState {
  ServiceState(const RouteTable& t, MetricsRegistry& m, EventBus& e) : table(t), metrics(m), events(e) {}
  const RouteTable& table;  // for the OpenAPI document, read when it is first asked for
  MetricsRegistry& metrics;
  EventBus& events;
  std::atomic<int> open_streams{0};
  std::once_flag openapi_once;
  std::string openapi_doc;
};

void add_service_routes(RouteTable& t, ServiceState& s);

}  // namespace ambdiag::server::detail
