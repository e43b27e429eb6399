// The REST side of the server (../shared/specs/cli.md "REST" and
// ../shared/specs/rest.md; docs/service.md lists every route):
//
//   GET /api/v1/health
//   GET /api/v1/pumps
//   GET /api/v1/pumps/{pump_id}/runs
//   GET /api/v1/pumps/{pump_id}/monitoring?since=TIME&limit=N   monitoring snapshots
//   GET /api/v1/runs/{run_id}              run_id URL-encoded ('/' as %2F, ':' as %3A)
//   GET /api/v1/runs/{run_id}/samples.f32  application/octet-stream, the exact bytes
//   pumps' models and references, runs' analyses and their files, jobs,
//   explain requests (rest.md), with `Authorization: Bearer TOKEN` and roles
//   pumps' trend series, trends and prognosis; a Grafana data source under
//   /api/v1/grafana (docs/service.md "Trends")
//
// JSON everywhere else; errors are {"error": "..."} with 400 (bad request),
// 401 (no or unknown token), 403 (role too low), 404 (unknown path, pump,
// run or job), 405 (method), 409 (state), 413 (body too large), 503 (a
// write on a server without the analysis service).
//
// It reads the historian through its own read connections (one per worker
// thread, opened on demand), so it runs beside the one writer (the DDS
// ingest of `ambdiag serve`) in the same process without locking it.
#pragma once

#include <cstddef>
#include <functional>
#include <memory>
#include <string>

#include <nlohmann/json.hpp>

namespace ambdiag::server {

class AnalysisService;

struct RestOptions {
  std::string db_path;          // must exist with the current schema (a writer creates it)
  std::string host = "0.0.0.0";
  int port = 0;                 // 0: any free port, see RestServer::port()
  // Each open connection holds a worker while it is served or kept alive, so
  // the pool bounds the clients served at once; idle keep-alive connections
  // are closed after keep_alive_timeout_s so they do not starve new clients.
  int worker_threads = 64;
  int keep_alive_timeout_s = 2;
  int keep_alive_max_requests = 1000;
  // Extra keys merged into GET /api/v1/health (e.g. ingest counters). Called
  // from worker threads, so it must be thread-safe.
  std::function<nlohmann::json()> health_extra;
  // Writes (models, references, explain) go to it; null: they answer 503.
  AnalysisService* analysis = nullptr;
  // Requests without a token act as `viewer` (rest.md, --anonymous-read).
  bool anonymous_read = false;
  int proposed_reference_runs = 3;        // shown as the proposed reference of a pump without one
  std::size_t max_body_bytes = 8u << 20;  // larger bodies: 413
};

class RestServer {
 public:
  // Opens one read connection to check the database; throws InputError if it
  // is missing, not a historian or of another schema version.
  explicit RestServer(RestOptions options);
  ~RestServer();  // stops and joins
  RestServer(const RestServer&) = delete;
  RestServer& operator=(const RestServer&) = delete;

  // Binds and serves on a background thread; returns the bound port. Throws
  // InputError if it cannot listen on host:port.
  int start();
  // Stops accepting, finishes the requests in flight, joins. Idempotent.
  void stop();
  int port() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Percent-encodes everything but RFC 3986 unreserved characters: how a
// run_id goes into a URL path segment.
std::string url_encode_segment(const std::string& s);

}  // namespace ambdiag::server
