#include "routes/service_routes.h"

#include <algorithm>
#include <memory>
#include <mutex>

#include "ambdiag/core/error.h"
#include "rest_json.h"
#include "routes/openapi.h"
#include "routes/route_context.h"

namespace ambdiag::server::detail {

namespace {

// Every route is in the table before the first request, so the document is
// made once, at the first one.
void openapi(RouteContext& c, ServiceState& s) {
  std::call_once(s.openapi_once,
                 [&] { s.openapi_doc = dump(openapi_document(s.table, c.opt.anonymous_read)); });
  c.res.status = 200;
  c.res.set_content(s.openapi_doc, "application/json");
}

std::optional<std::uint64_t> last_event_id(const httplib::Request& req) {
  if (!req.has_header("Last-Event-ID")) return std::nullopt;
  const std::string v = req.get_header_value("Last-Event-ID");
  if (v.empty() || v.size() > 19 || v.find_first_not_of("0123456789") != std::string::npos)
    throw InputError("Last-Event-ID: '" + v.substr(0, 40) + "' is not an event id (a decimal integer)");
  return std::stoull(v);
}

// The stream holds one of httplib's worker threads while it is open (a
// content provider runs on the connection's thread), so at most
// max_event_streams (and at most half the pool) are open at once, the rest
// of the pool stays for the API; beyond, 503.
void events(RouteContext& c, ServiceState& s) {
  const auto last = last_event_id(c.req);
  // Never more than half the workers, whatever is configured.
  const int limit = std::max(0, std::min(c.opt.max_event_streams, std::max(1, c.opt.worker_threads) / 2));
  if (s.open_streams.fetch_add(1) >= limit) {
    s.open_streams.fetch_sub(1);
    c.res.set_header("Retry-After", "10");
    return send_error(c.res, 503,
                      "too many event streams open (at most " + std::to_string(limit) + "); retry later");
  }
  std::shared_ptr<EventBus::Subscription> sub =
      s.events.subscribe(last, static_cast<size_t>(std::max(1, c.opt.event_queue_max)));
  const auto heartbeat = std::chrono::milliseconds(std::max(10, c.opt.event_heartbeat_ms));
  auto first = std::make_shared<bool>(true);
  c.res.status = 200;
  c.res.set_header("Cache-Control", "no-cache");
  c.res.set_header("X-Accel-Buffering", "no");  // proxies: pass each event on at once
  c.res.set_chunked_content_provider(
      "text/event-stream",
      [sub, heartbeat, first](size_t, httplib::DataSink& sink) {
        std::string out;
        if (*first) {
          // The browser's reconnect delay, and something at once so that a
          // client knows the stream is open before the first event.
          out = "retry: 2000\n: ambdiag events\n\n";
          *first = false;
        }
        const auto events = sub->wait(out.empty() ? heartbeat : std::chrono::milliseconds(0));
        if (sub->dropped()) return false;  // too slow: closed, the client reconnects with Last-Event-ID
        if (sub->ended()) {
          sink.done();  // the server stops
          return true;
        }
        for (const auto& e : events) out += sse_frame(e);
        if (out.empty()) out = ": heartbeat\n\n";  // keeps proxies from closing an idle stream
        return sink.write(out.data(), out.size());
      },
      [&s](bool) { s.open_streams.fetch_sub(1); });
}

}  // namespace

void add_service_routes(RouteTable& t, ServiceState& s) {
  using storage::Role;
  t.add({"GET", "/api/v1/openapi.json", Role::viewer,
         "this document: OpenAPI 3.1 of every route the server answers",
         [&s](RouteContext& c, const PathParams&) { openapi(c, s); }})
      .description = "Generated from the server's route table.";
  auto& m = t.add({"GET",
                   "/metrics",
                   std::nullopt,
                   "the service's own metrics, Prometheus text exposition format 0.0.4",
                   [&s](RouteContext& c, const PathParams&) {
                     c.res.status = 200;
                     c.res.set_content(s.metrics.render(), "text/plain; version=0.0.4; charset=utf-8");
                   },
                   {},
                   "text/plain"});
  m.description =
      "Runs received, rejected DDS samples by reason, jobs by kind and status, job durations, HTTP requests "
      "by route pattern, method and status, request durations, event streams (docs/service.md \"Metrics\").";
  auto& e =
      t.add({"GET",
             "/api/v1/events",
             Role::viewer,
             "live updates: a server-sent-events stream of new runs, run status changes, finished jobs, "
             "models, references and alarm transitions",
             [&s](RouteContext& c, const PathParams&) { events(c, s); },
             {{"access_token",
               "the token, for clients that cannot set the Authorization header (a browser's EventSource)"}},
             "text/event-stream"});
  e.token_in_query = true;
  e.description =
      "Each event: `id` (increasing), `event` (its type: run.new, run.status, job.done, job.failed, model.new, "
      "reference.new, reload, ...) and `data` (one JSON object). A client reconnecting with the Last-Event-ID "
      "header gets the events it missed while they are still held (the last 4096), otherwise first a `reload` "
      "event. Comments (`: heartbeat`) keep idle streams open. At most max_event_streams streams at once "
      "(503 beyond); a client too slow to take its events is disconnected.";
}

}  // namespace ambdiag::server::detail
