#include "ambdiag/server/rest_server.h"

#include <httplib.h>

#include <chrono>
#include <cmath>
#include <optional>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/server/events.h"
#include "ambdiag/server/metrics.h"
#include "events/event_tail.h"
#include "http_compress.h"
#include "rate_limit.h"
#include "reader_pool.h"
#include "rest_tls.h"
#include "routes/route_context.h"
#include "routes/service_routes.h"
#include "url.h"

namespace ambdiag::server {

using detail::send_error;

namespace {

// An exception out of a handler as its status and {"error"}.
void send_exception(httplib::Response& res, std::exception_ptr ep) {
  try {
    std::rethrow_exception(ep);
  } catch (const InputError& e) {
    send_error(res, 400, e.what());
  } catch (const NotFoundError& e) {
    send_error(res, 404, e.what());
  } catch (const GoneError& e) {
    send_error(res, 410, e.what());
  } catch (const ConflictError& e) {
    send_error(res, 409, e.what());
  } catch (const std::exception& e) {
    send_error(res, 500, std::string("internal error: ") + e.what());
  } catch (...) {
    send_error(res, 500, "internal error");
  }
}

// A bounded label: one of the methods httplib routes, else "other".
std::string method_label(const std::string& m) {
  for (const char* known : {"GET", "HEAD", "POST", "PUT", "PATCH", "DELETE", "OPTIONS"})
    if (m == known) return m;
  return "other";
}

constexpr const char* kUnmatched = "unmatched";  // the route label of a path no route has

int reader_count(const RestOptions& o) {
  const int workers = std::max(1, o.worker_threads);
  if (o.db_readers > 0) return std::min(o.db_readers, workers);
  return storage::is_postgres_location(o.db_path) ? std::min(RestOptions::kDefaultPgReaders, workers) : workers;
}

}  // namespace

struct RestServer::Impl {
  RestOptions opt;
  detail::ReaderPool pool;
  detail::RouteTable routes;
  std::unique_ptr<MetricsRegistry> own_metrics;  // when opt.metrics is null
  std::unique_ptr<EventBus> own_events;          // when opt.events is null
  MetricsRegistry& metrics;
  EventBus& events;
  std::unique_ptr<detail::EventTail> tail;  // the events table into `events`
  detail::ServiceState service;
  detail::RateLimiter limiter;
  MetricFamily<Counter>& requests;
  MetricFamily<Histogram>& durations;
  Counter& rate_limited;
  const std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  // HTTPS only with a certificate and key (TLS 1.2+), plain HTTP without.
  std::unique_ptr<httplib::Server> server;
  httplib::Server& http;
  std::thread thread;
  int port = 0;

  explicit Impl(RestOptions o)
      : opt(std::move(o)),
        pool(opt.db_path, reader_count(opt)),
        own_metrics(opt.metrics ? nullptr : std::make_unique<MetricsRegistry>()),
        own_events(opt.events ? nullptr : std::make_unique<EventBus>()),
        metrics(opt.metrics ? *opt.metrics : *own_metrics),
        events(opt.events ? *opt.events : *own_events),
        tail(opt.event_poll_ms > 0 ? std::make_unique<detail::EventTail>(opt.db_path, events,
                                                                          std::chrono::milliseconds(opt.event_poll_ms),
                                                                          opt.event_notify)
                                   : nullptr),
        service{routes, metrics, events},
        limiter(opt.rate_limit_per_s, opt.rate_limit_burst),
        requests(metrics.counter("ambdiag_http_requests_total",
                                 "HTTP requests answered, by route pattern (\"unmatched\": no route has the path), method and status.",
                                 {"route", "method", "status"})),
        durations(metrics.histogram("ambdiag_http_request_duration_seconds",
                                    "Time in the request's handler (a streamed body's transfer not included), by route pattern and method.",
                                    {"route", "method"}, default_seconds_buckets())),
        rate_limited(metrics.counter("ambdiag_http_rate_limited_total", "Requests refused with 429 by the per-token rate limit.").with({})),
        server(opt.tls_cert_path.empty() ? std::make_unique<httplib::Server>()
                                         : detail::make_tls_server(opt.tls_cert_path, opt.tls_key_path)),
        http(*server) {
    detail::add_read_routes(routes, started);
    detail::add_analysis_routes(routes);
    detail::add_alarm_routes(routes);
    detail::add_trend_routes(routes);
    detail::add_grafana_routes(routes);
    detail::add_service_routes(routes, service);
    detail::add_web_routes(routes);
    detail::add_retention_routes(routes);
    register_metrics();
    // A client that reconnects with an id older than the ring gets the
    // events after it from the table, on any server.
    if (tail) events.set_history(detail::events_table_history(pool));
  }

  ~Impl() {
    if (tail) events.set_history({});  // a bus given in the options outlives this server
  }

  // What the server itself knows: the historian's jobs and runs (read at
  // each scrape through the reader pool), uptime, event streams.
  void register_metrics() {
    metrics.gauge("ambdiag_build_info", "The server's version (value 1).", {"version"}).with({"0.1.0"}).set(1);
    metrics.collected_value("ambdiag_uptime_seconds", "Seconds since the REST server started.", MetricType::gauge,
                            [this] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(); });
    metrics.collected_value("ambdiag_historian_runs", "Runs held by the historian (every status).", MetricType::gauge,
                            [this] { return static_cast<double>(pool.acquire()->count_runs()); });
    metrics.collected("ambdiag_jobs", "Jobs in the historian's queue by kind and status (every server on the database).",
                      MetricType::gauge, {"kind", "status"}, [this] {
                        auto h = pool.acquire();
                        std::vector<MetricSample> out;
                        for (const auto& [key, n] : h->count_jobs_by_kind_and_status())
                          out.push_back({{key.first, key.second}, static_cast<double>(n)});
                        return out;
                      });
    metrics.collected("ambdiag_alarms_active", "Active alarms (condition holds or latched) by severity, every server on the database.",
                      MetricType::gauge, {"severity"}, [this] {
                        auto by = pool.acquire()->count_active_alarms_by_severity();
                        std::vector<MetricSample> out;
                        for (const char* sev : {"low", "medium", "high", "critical"})  // every severity, 0 included
                          out.push_back({{sev}, static_cast<double>(by[sev])});
                        return out;
                      });
    metrics.collected_value("ambdiag_event_streams", "Event streams (GET /api/v1/events) open now.", MetricType::gauge,
                            [this] { return static_cast<double>(service.open_streams.load()); });
    metrics.collected_value("ambdiag_event_streams_dropped_total", "Event streams closed because their client did not keep up.",
                            MetricType::counter, [this] { return static_cast<double>(events.dropped_total()); });
    metrics.collected_value("ambdiag_events_last_id", "The id of the newest event published (ids grow by one per event).",
                            MetricType::gauge, [this] { return static_cast<double>(events.last_id()); });
    if (!tail) return;
    metrics.collected_value("ambdiag_event_tail_polls_total",
                            "Reads of the events table (each period, and at each notification on PostgreSQL).",
                            MetricType::counter, [this] { return static_cast<double>(tail->polls()); });
    metrics.collected_value("ambdiag_event_notifications_total",
                            "PostgreSQL notifications of committed events received (0 on SQLite: the poll alone).",
                            MetricType::counter, [this] { return static_cast<double>(tail->notifications()); });
  }

  void count(const std::string& method, const std::string& route, int status, std::chrono::steady_clock::time_point t0) {
    const std::string m = method_label(method);
    requests.with({route, m, std::to_string(status)}).inc();
    durations.with({route, m}).observe(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }

  void handle(const httplib::Request& req, httplib::Response& res) {
    const auto t0 = std::chrono::steady_clock::now();
    std::string route = kUnmatched;
    try {
      dispatch(req, res, route);
    } catch (...) {
      send_exception(res, std::current_exception());
    }
    detail::gzip_reply(req, res);  // not httplib's brotli: seconds for a megabyte (http_compress.h)
    count(req.method, route, res.status == -1 ? 200 : res.status, t0);  // httplib's default: 200
  }

  void dispatch(const httplib::Request& req, httplib::Response& res, std::string& route_label) {
    const auto segments = detail::split_path(req.target);
    if (!segments) return send_error(res, 400, "bad path or percent-encoding: " + req.target);
    const auto found = routes.find(req.method, *segments);
    if (!found.route) {
      if (!found.path_known) return send_error(res, 404, "no such resource: " + req.path);
      res.set_header("Allow", found.allow);
      return send_error(res, 405, req.method + " not allowed on " + req.path + " (allowed: " + found.allow + ")");
    }
    const detail::Route& route = *found.route;
    route_label = route.pattern;
    std::optional<detail::Caller> caller;
    if (route.role) {
      caller = detail::authorize(pool, req, *route.role, opt.anonymous_read, res, route.token_in_query);
      if (!caller) return;  // 401 or 403 sent
      if (!rate_ok(*caller, req, res)) return;
    }
    if (route.method != "GET" && !route.read_only && !route.writes_elsewhere && !opt.analysis)
      return send_error(res, 503, "this server runs without the analysis service: " + req.method + " " + req.path + " is not served");
    detail::RouteContext ctx{pool, opt, caller.value_or(detail::Caller{}), req, res};
    route.handler(ctx, found.params);
  }

  // The token's bucket, or the client address' for a request without one;
  // 429 naming the limit when it is empty.
  bool rate_ok(const detail::Caller& caller, const httplib::Request& req, httplib::Response& res) {
    if (!limiter.enabled()) return true;
    const std::string key = caller.from_token ? "token " + caller.name : "address " + req.remote_addr;
    const double wait_s = limiter.take(key);
    if (wait_s <= 0) return true;
    rate_limited.inc();
    res.set_header("Retry-After", std::to_string(std::max(1, static_cast<int>(std::ceil(wait_s)))));
    send_error(res, 429, "rate limit of " + (caller.from_token ? "token '" + caller.name + "'" : "address " + req.remote_addr) +
                             " exceeded: " + format_metric_value(limiter.per_s()) + " requests/s, bursts of " +
                             format_metric_value(limiter.burst()) + " (ambdiag serve --rate-limit)");
    return false;
  }
};

RestServer::RestServer(RestOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  auto& http = impl_->http;
  auto* impl = impl_.get();
  const int workers = std::max(1, impl->opt.worker_threads);
  http.new_task_queue = [workers] { return new httplib::ThreadPool(static_cast<size_t>(workers)); };
  http.set_tcp_nodelay(true);  // small JSON replies: 310 -> 31k requests/s (STACK.md)
  http.set_keep_alive_timeout(std::max(1, impl->opt.keep_alive_timeout_s));
  http.set_keep_alive_max_count(static_cast<size_t>(std::max(1, impl->opt.keep_alive_max_requests)));
  http.set_read_timeout(5, 0);
  http.set_payload_max_length(impl->opt.max_body_bytes);  // beyond: 413 before the handler runs
  const auto handle = [impl](const httplib::Request& req, httplib::Response& res) { impl->handle(req, res); };
  http.Get(".*", handle);
  http.Post(".*", handle);
  http.Put(".*", handle);
  http.Patch(".*", handle);
  http.Delete(".*", handle);
  http.Options(".*", handle);
  http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) { send_exception(res, ep); });
  // httplib's own refusals (malformed request line, too long URI, body too
  // large, ...) as JSON too, and counted: handle() never saw them (an
  // empty body tells them from the errors handle() sent).
  http.set_error_handler([impl](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    send_error(res, res.status, "HTTP " + std::to_string(res.status));
    impl->count(req.method, kUnmatched, res.status, std::chrono::steady_clock::now());
  });
}

RestServer::~RestServer() { stop(); }

int RestServer::start() {
  auto& o = impl_->opt;
  if (impl_->thread.joinable()) return impl_->port;
  const int port = o.port == 0 ? impl_->http.bind_to_any_port(o.host) : (impl_->http.bind_to_port(o.host, o.port) ? o.port : -1);
  if (port <= 0) throw InputError("REST: cannot listen on " + o.host + ":" + std::to_string(o.port));
  impl_->port = port;
  if (impl_->tail) impl_->tail->start();
  impl_->thread = std::thread([this] { impl_->http.listen_after_bind(); });
  return port;
}

void RestServer::stop() {
  if (!impl_ || !impl_->thread.joinable()) return;
  impl_->events.close();  // ends the open event streams, which would hold their workers
  impl_->http.stop();
  impl_->thread.join();
  if (impl_->tail) impl_->tail->stop();
}

int RestServer::port() const { return impl_->port; }

}  // namespace ambdiag::server
