// The read side that came first (cli.md "REST"): health, pumps, runs, a
// run's samples, monitoring snapshots.
#include <limits>

#include "ambdiag/storage/historian.h"
#include "analysis/views.h"
#include "rest_json.h"
#include "routes/api_schemas.h"
#include "routes/route_context.h"

namespace ambdiag::server::detail {

namespace {

void pumps(RouteContext& c) {
  auto h = c.pool.acquire();
  nlohmann::json list = nlohmann::json::array();
  for (const auto& p : h->list_pumps()) list.push_back(pump_json(p));
  send_json(c.res, 200, {{"pumps", list}});
}

void pump_runs(RouteContext& c, const std::string& pump_id) {
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  if (!h->find_pump(pump_id)) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  nlohmann::json list = nlohmann::json::array();
  for (const auto& r : h->list_runs(pump_id)) list.push_back(run_json(r, false));
  send_json(c.res, 200, {{"pump_id", pump_id}, {"runs", list}});
}

// ?since=TIME (UTC ISO 8601 or ns since the epoch, inclusive; default:
// all) &limit=N (1..10000, default 1000); oldest first. When the limit
// cut the list, "next_since" is where the next page starts.
void pump_monitoring(RouteContext& c, const std::string& pump_id) {
  constexpr std::int64_t kMaxLimit = 10000;
  std::int64_t since = std::numeric_limits<std::int64_t>::min(), limit = 1000;
  if (c.req.has_param("since")) since = storage::ns_from_utc(c.req.get_param_value("since"), "since");
  if (c.req.has_param("limit")) {
    const std::string l = c.req.get_param_value("limit");
    if (l.empty() || l.size() > 6 || l.find_first_not_of("0123456789") != std::string::npos || std::stoll(l) < 1 ||
        std::stoll(l) > kMaxLimit)
      return send_error(c.res, 400, "limit: '" + l + "' is not an integer in 1.." + std::to_string(kMaxLimit));
    limit = std::stoll(l);
  }
  auto h = c.pool.acquire();
  auto snap = h->snapshot();
  if (!h->find_pump(pump_id)) return send_error(c.res, 404, "no pump '" + pump_id + "'");
  const auto list = h->list_monitoring(pump_id, since, limit + 1);  // one more: is there a next page?
  nlohmann::json out = nlohmann::json::array();
  for (size_t i = 0; i < list.size() && static_cast<std::int64_t>(i) < limit; ++i) out.push_back(monitoring_json(list[i]));
  nlohmann::json j = {{"pump_id", pump_id}, {"limit", limit}, {"snapshots", out}};
  if (static_cast<std::int64_t>(list.size()) > limit) j["next_since"] = storage::utc_from_ns(list.back().time_ns);
  send_json(c.res, 200, j);
}

void run(RouteContext& c, const std::string& run_id) {
  auto h = c.pool.acquire();
  const auto r = h->find_run(run_id);
  if (!r) return send_error(c.res, 404, "no run '" + run_id + "'");
  send_json(c.res, 200, run_json(*r, true));
}

// Streams the chunks from one read snapshot, so the announced length and
// the bytes agree even while the writer adds chunks.
void samples(RouteContext& c, const std::string& run_id) {
  struct Download {
    ReaderPool::Lease lease;
    std::optional<storage::Historian::Snapshot> snap;  // declared after: released first
  };
  auto d = std::make_shared<Download>(Download{c.pool.acquire(), std::nullopt});
  d->snap.emplace(d->lease->snapshot());
  const auto r = d->lease->find_run(run_id);
  if (!r) return send_error(c.res, 404, "no run '" + run_id + "'");
  if (r->samples_dropped_at) return send_error(c.res, 410, dropped_by_retention(*r, true));
  c.res.status = 200;
  c.res.set_header("X-Run-Status", storage::to_string(r->status));
  // No chunk yet (a run just begun): an empty body with Content-Length 0.
  // httplib takes a provider of length 0 as "length unknown": it would
  // call ours again and again at offset 0 (nothing written, never done)
  // and the client would wait for its read timeout.
  if (r->samples_bytes() == 0) {
    c.res.set_content("", "application/octet-stream");
    return;
  }
  c.res.set_content_provider(
      static_cast<size_t>(r->samples_bytes()), "application/octet-stream",
      [d, run_id](size_t offset, size_t, httplib::DataSink& sink) {
        if (offset != 0) return false;  // everything is written in the first call
        try {  // runs after the handler, outside httplib's exception handler
          return d->lease->stream_samples(run_id, [&](std::span<const std::uint8_t> b) {
            return sink.write(reinterpret_cast<const char*>(b.data()), b.size());
          });
        } catch (const std::exception&) {
          return false;  // the client sees a short body and a closed connection
        }
      },
      [d](bool) mutable { d.reset(); });
}

}  // namespace

void add_read_routes(RouteTable& t, std::chrono::steady_clock::time_point started) {
  using storage::Role;
  using namespace schema;
  add_read_schemas(t);
  t.add({"GET", "/api/v1/health", std::nullopt, "liveness, schema version, run count, uptime (no token needed)",
         [started](RouteContext& c, const PathParams&) {
           auto h = c.pool.acquire();
           nlohmann::json j = {{"status", "ok"},
                               {"service", "ambdiag"},
                               {"version", "0.1.0"},
                               {"schema_version", storage::Historian::schema_version()},
                               {"runs", h->count_runs()},
                               {"uptime_s", std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()}};
           if (c.opt.health_extra) j.update(c.opt.health_extra());
           send_json(c.res, 200, j);
         }})
      .response_schema = ref("Health");
  t.add({"GET", "/api/v1/pumps", Role::viewer, "every pump the historian knows", [](RouteContext& c, const PathParams&) { pumps(c); }})
      .response_schema = object({{"pumps", array(ref("PumpSummary"))}});
  t.add({"GET", "/api/v1/pumps/{pump_id}/runs", Role::viewer, "a pump's runs, oldest first",
         [](RouteContext& c, const PathParams& p) { pump_runs(c, p.at("pump_id")); }})
      .response_schema = object({{"pump_id", string()}, {"runs", array(ref("Run"))}});
  t.add({"GET", "/api/v1/pumps/{pump_id}/monitoring", Role::viewer, "a pump's monitoring snapshots, oldest first",
         [](RouteContext& c, const PathParams& p) { pump_monitoring(c, p.at("pump_id")); },
         {{"since", "from this time on (ISO 8601 UTC or ns since the epoch, inclusive)"}, {"limit", "at most this many (1..10000, default 1000)"}}})
      .response_schema = object({{"pump_id", string()}, {"limit", integer()}, {"snapshots", array(ref("MonitoringSnapshot"))}},
                                {{"next_since", time()}});
  t.add({"GET", "/api/v1/runs/{run_id*}", Role::viewer, "a run: status, header, counts",
         [](RouteContext& c, const PathParams& p) { run(c, p.at("run_id")); }})
      .response_schema = ref("Run");
  t.add({"GET", "/api/v1/runs/{run_id*}/samples.f32", Role::viewer, "the run's samples exactly as a recording's samples.f32",
         [](RouteContext& c, const PathParams& p) { samples(c, p.at("run_id")); }, {}, "application/octet-stream"})
      .errors = {410};
}

}  // namespace ambdiag::server::detail
