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
//   GET /api/v1/openapi.json              OpenAPI 3.1 of every route (from the route table)
//   GET /metrics                           Prometheus text format 0.0.4, no token
//   GET /api/v1/events                     server-sent events (new runs, jobs, ...)
//   GET /, GET /ui/{path}                  the web UI's files (RestOptions::web_dir), no token
//
// JSON everywhere else; errors are {"error": "..."} with 400 (bad request),
// 401 (no or unknown token), 403 (role too low), 404 (unknown path, pump,
// run or job), 405 (method), 409 (state), 413 (body too large), 429 (rate
// limit), 503 (a write on a server without the analysis service, too many
// event streams).
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
class EventBus;
class MetricsRegistry;
class RetentionService;

struct RestOptions {
  std::string db_path;          // must exist with the current schema (a writer creates it)
  std::string host = "0.0.0.0";
  int port = 0;                 // 0: any free port, see RestServer::port()
  // Each open connection holds a worker while it is served or kept alive, so
  // the pool bounds the clients served at once; idle keep-alive connections
  // are closed after keep_alive_timeout_s so they do not starve new clients.
  int worker_threads = 64;
  // Read connections to the historian the workers share (a request waits
  // for one while all are lent out). 0: one per worker thread on SQLite (a
  // file handle each), kDefaultPgReaders on PostgreSQL, where each is a
  // server process (docs/deployment.md "Connections"). At most worker_threads.
  int db_readers = 0;
  static constexpr int kDefaultPgReaders = 16;
  int keep_alive_timeout_s = 2;
  int keep_alive_max_requests = 1000;
  // Extra keys merged into GET /api/v1/health (e.g. ingest counters). Called
  // from worker threads, so it must be thread-safe.
  std::function<nlohmann::json()> health_extra;
  // Writes (models, references, explain) go to it; null: they answer 503.
  AnalysisService* analysis = nullptr;
  // Retention policies: PUTs go to it and its defaults are shown; null:
  // the built-in defaults are shown and a PUT answers 503.
  RetentionService* retention = nullptr;
  // Requests without a token act as `viewer` (rest.md, --anonymous-read).
  bool anonymous_read = false;
  int proposed_reference_runs = 3;        // shown as the proposed reference of a pump without one
  std::size_t max_body_bytes = 8u << 20;  // larger bodies: 413
  // Both set: HTTPS only (TLS 1.2 or later) with this PEM certificate chain
  // and key (docs/service.md, "HTTPS"); the constructor throws InputError
  // naming the file if one is missing, unreadable or not the other's match.
  std::string tls_cert_path, tls_key_path;
  // GET /metrics renders it; the server registers its own families in it
  // (HTTP requests, jobs, streams). Null: the server makes its own. One
  // RestServer per registry.
  MetricsRegistry* metrics = nullptr;
  // GET /api/v1/events streams it. Null: the server makes its own. The
  // server publishes the historian's events table into it (every
  // process' events, by their seq), polling every event_poll_ms; 0: no
  // polling (then only what is published to it directly shows). On
  // PostgreSQL, with event_notify, a connection LISTENs for the NOTIFY of
  // each append and polls at once: the period is then the fallback
  // (false: the period alone, for measuring it; docs/benchmarks.md).
  EventBus* events = nullptr;
  int event_poll_ms = 250;
  bool event_notify = true;
  // Event streams open at once (each holds a worker thread; 503 beyond;
  // never more than half of worker_threads),
  // the heartbeat of an idle stream, and the events queued for a slow
  // client before it is disconnected.
  int max_event_streams = 16;
  int event_heartbeat_ms = 15000;
  int event_queue_max = 1024;
  // Requests per second per token (per client address without one), with
  // bursts of rate_limit_burst; 0: no limit (the default here: `ambdiag
  // serve` sets 50 in bursts of 100 unless --rate-limit says otherwise).
  // Open routes are not limited.
  double rate_limit_per_s = 0;
  double rate_limit_burst = 100;
  // The web UI's built files (GET / and /ui/...; web/README.md); "": GET /
  // answers 404 saying the UI is not installed.
  std::string web_dir;
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

// Where the web UI's built files are for a server binary at `exe`: the
// first of EXE_DIR/../web (the build tree: build/cli/ambdiag and
// build/web) and EXE_DIR/../share/ambdiag/web (installed) that holds an
// index.html; "" when neither does.
std::string find_web_dir(const std::string& exe);

// Percent-encodes everything but RFC 3986 unreserved characters: how a
// run_id goes into a URL path segment.
std::string url_encode_segment(const std::string& s);

}  // namespace ambdiag::server
