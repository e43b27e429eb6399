// GET /api/v1/health of a server on a loopback port, read with a short
// timeout (a killed or paused server answers nothing): the failover tests
// poll it to see who holds an ingest group.
#pragma once

#include <httplib.h>

#include <nlohmann/json.hpp>

namespace ambdiag::testing {

// The health object; an empty object when the server does not answer.
inline nlohmann::json health_on_port(int port) {
  httplib::Client c("127.0.0.1", port);
  c.set_connection_timeout(0, 300000);
  c.set_read_timeout(1, 0);
  const auto r = c.Get("/api/v1/health");
  if (!r || r->status != 200) return nlohmann::json::object();
  return nlohmann::json::parse(r->body, nullptr, false);
}

// Its first ingest group (role, holder, epoch, takeovers, lost), or an empty object.
inline nlohmann::json ingest_group_on_port(int port) {
  const auto h = health_on_port(port);
  return h.is_object() && h.contains("ingest_groups") ? h["ingest_groups"][0] : nlohmann::json::object();
}

}  // namespace ambdiag::testing
