#include "ambdiag/server/rest_server.h"

#include <httplib.h>

#include <chrono>
#include <limits>
#include <optional>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "reader_pool.h"
#include "rest_routes.h"
#include "rest_json.h"
#include "url.h"

namespace ambdiag::server {

namespace {

using Segments = std::vector<std::string>;

using detail::send_error;
using detail::send_json;

// Joins segments [from, to) with '/': a run_id sent with its '/' unencoded
// still finds its run.
std::string join(const Segments& s, size_t from, size_t to) {
  std::string out;
  for (size_t i = from; i < to; ++i) out += (i > from ? "/" : "") + s[i];
  return out;
}

enum class Route {
  health, pumps, pump, pump_runs, pump_monitoring, pump_model, pump_models, pump_reference,
  run, samples, run_analysis, run_file, run_explain,
  jobs, job, job_file, job_adopt, job_cancel, none
};

struct Match {
  Route route = Route::none;
  std::string id;    // pump_id, run_id or job_id
  std::string name;  // a file's name
};

// The files of a run's analysis served under the run's URL.
bool is_run_file(const std::string& s) {
  return s == "frf.csv" || s == "bode.svg" || s == "stabilization.svg" || s == "diagnosis.svg";
}

Match match(const Segments& s) {
  if (s.size() < 3 || s[0] != "api" || s[1] != "v1") return {};
  if (s.size() == 3 && s[2] == "health") return {Route::health, "", ""};
  if (s[2] == "pumps") {
    if (s.size() == 3) return {Route::pumps, "", ""};
    if (s[3].empty()) return {};
    if (s.size() == 4) return {Route::pump, s[3], ""};
    if (s.size() != 5) return {};
    if (s[4] == "runs") return {Route::pump_runs, s[3], ""};
    if (s[4] == "monitoring") return {Route::pump_monitoring, s[3], ""};
    if (s[4] == "model") return {Route::pump_model, s[3], ""};
    if (s[4] == "models") return {Route::pump_models, s[3], ""};
    if (s[4] == "reference") return {Route::pump_reference, s[3], ""};
    return {};
  }
  if (s[2] == "runs" && s.size() >= 4) {
    if (s.size() >= 5) {
      const std::string& last = s.back();
      const std::string id = join(s, 3, s.size() - 1);
      if (last == "samples.f32") return {Route::samples, id, ""};
      if (last == "analysis") return {Route::run_analysis, id, ""};
      if (last == "explain") return {Route::run_explain, id, ""};
      if (is_run_file(last)) return {Route::run_file, id, last};
    }
    return {Route::run, join(s, 3, s.size()), ""};
  }
  if (s[2] == "jobs") {
    if (s.size() == 3) return {Route::jobs, "", ""};
    if (s.size() == 4) return {Route::job, s[3], ""};
    if (s.size() == 5 && s[4] == "adopt") return {Route::job_adopt, s[3], ""};
    if (s.size() == 5 && s[4] == "cancel") return {Route::job_cancel, s[3], ""};
    if (s.size() == 6 && s[4] == "files") return {Route::job_file, s[3], s[5]};
  }
  return {};
}

// Which method each route answers and the role it needs (rest.md "Who may
// do what"); nullopt: method not allowed.
struct Access {
  bool allowed;
  std::optional<storage::Role> role;  // nullopt: open to all (health)
};
Access access(Route r, const std::string& method) {
  using storage::Role;
  const bool get = method == "GET" || method == "HEAD";
  switch (r) {
    case Route::health: return {get, std::nullopt};
    case Route::pump_model:
    case Route::pump_reference:
      if (method == "PUT") return {true, Role::engineer};
      return {get, Role::viewer};
    case Route::run_explain:
    case Route::job_adopt:
    case Route::job_cancel: return {method == "POST", Role::engineer};
    default: return {get, Role::viewer};
  }
}

std::string allow_header(Route r) {
  switch (r) {
    case Route::pump_model:
    case Route::pump_reference: return "GET, HEAD, PUT";
    case Route::run_explain:
    case Route::job_adopt:
    case Route::job_cancel: return "POST";
    default: return "GET, HEAD";
  }
}

}  // namespace

struct RestServer::Impl {
  RestOptions opt;
  detail::ReaderPool pool;
  httplib::Server http;
  std::thread thread;
  int port = 0;
  const std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();

  explicit Impl(RestOptions o) : opt(std::move(o)), pool(opt.db_path, std::max(1, opt.worker_threads)) {}

  void handle(const httplib::Request& req, httplib::Response& res) {
    const auto segments = detail::split_path(req.target);
    if (!segments) return send_error(res, 400, "bad path or percent-encoding: " + req.target);
    const Match m = match(*segments);
    if (m.route == Route::none) return send_error(res, 404, "no such resource: " + req.path);
    const Access a = access(m.route, req.method);
    if (!a.allowed) {
      res.set_header("Allow", allow_header(m.route));
      return send_error(res, 405, req.method + " not allowed on " + req.path + " (allowed: " + allow_header(m.route) + ")");
    }
    std::optional<detail::Caller> caller;
    if (a.role) {
      caller = detail::authorize(pool, req, *a.role, opt.anonymous_read, res);
      if (!caller) return;  // 401 or 403 sent
    }
    const bool write = req.method == "PUT" || req.method == "POST";
    if (write && !opt.analysis)
      return send_error(res, 503, "this server runs without the analysis service: " + req.method + " " + req.path + " is not served");
    detail::RouteContext ctx{pool, opt, caller.value_or(detail::Caller{}), req, res};
    switch (m.route) {
      case Route::health: return health(res);
      case Route::pumps: return pumps(res);
      case Route::pump_runs: return pump_runs(res, m.id);
      case Route::pump_monitoring: return pump_monitoring(req, res, m.id);
      case Route::run: return run(res, m.id);
      case Route::samples: return samples(res, m.id);
      case Route::pump: return detail::get_pump(ctx, m.id);
      case Route::pump_model: return write ? detail::put_model(ctx, m.id) : detail::get_model(ctx, m.id);
      case Route::pump_models: return detail::get_models(ctx, m.id);
      case Route::pump_reference: return write ? detail::put_reference(ctx, m.id) : detail::get_reference(ctx, m.id);
      case Route::run_analysis: return detail::get_analysis(ctx, m.id);
      case Route::run_file: return detail::get_run_file(ctx, m.id, m.name);
      case Route::run_explain: return detail::post_explain(ctx, m.id);
      case Route::jobs: return detail::get_jobs(ctx);
      case Route::job: return detail::get_job(ctx, m.id);
      case Route::job_file: return detail::get_job_file(ctx, m.id, m.name);
      case Route::job_adopt: return detail::post_adopt(ctx, m.id);
      case Route::job_cancel: return detail::post_cancel(ctx, m.id);
      case Route::none: break;
    }
    send_error(res, 404, "no such resource: " + req.path);
  }

  void health(httplib::Response& res) {
    auto h = pool.acquire();
    nlohmann::json j = {
        {"status", "ok"},
        {"service", "ambdiag"},
        {"version", "0.1.0"},
        {"schema_version", storage::Historian::schema_version()},
        {"runs", h->count_runs()},
        {"uptime_s", std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()}};
    if (opt.health_extra) j.update(opt.health_extra());
    send_json(res, 200, j);
  }

  void pumps(httplib::Response& res) {
    auto h = pool.acquire();
    nlohmann::json list = nlohmann::json::array();
    for (const auto& p : h->list_pumps()) list.push_back(detail::pump_json(p));
    send_json(res, 200, {{"pumps", list}});
  }

  void pump_runs(httplib::Response& res, const std::string& pump_id) {
    auto h = pool.acquire();
    auto snap = h->snapshot();
    if (!h->find_pump(pump_id)) return send_error(res, 404, "no pump '" + pump_id + "'");
    nlohmann::json list = nlohmann::json::array();
    for (const auto& r : h->list_runs(pump_id)) list.push_back(detail::run_json(r, false));
    send_json(res, 200, {{"pump_id", pump_id}, {"runs", list}});
  }

  // ?since=TIME (UTC ISO 8601 or ns since the epoch, inclusive; default:
  // all) &limit=N (1..10000, default 1000); oldest first. When the limit
  // cut the list, "next_since" is where the next page starts.
  void pump_monitoring(const httplib::Request& req, httplib::Response& res, const std::string& pump_id) {
    constexpr std::int64_t kMaxLimit = 10000;
    std::int64_t since = std::numeric_limits<std::int64_t>::min(), limit = 1000;
    if (req.has_param("since")) since = storage::ns_from_utc(req.get_param_value("since"), "since");
    if (req.has_param("limit")) {
      const std::string l = req.get_param_value("limit");
      if (l.empty() || l.size() > 6 || l.find_first_not_of("0123456789") != std::string::npos ||
          std::stoll(l) < 1 || std::stoll(l) > kMaxLimit)
        return send_error(res, 400, "limit: '" + l + "' is not an integer in 1.." + std::to_string(kMaxLimit));
      limit = std::stoll(l);
    }
    auto h = pool.acquire();
    auto snap = h->snapshot();
    if (!h->find_pump(pump_id)) return send_error(res, 404, "no pump '" + pump_id + "'");
    const auto list = h->list_monitoring(pump_id, since, limit + 1);  // one more: is there a next page?
    nlohmann::json out = nlohmann::json::array();
    for (size_t i = 0; i < list.size() && static_cast<std::int64_t>(i) < limit; ++i)
      out.push_back(detail::monitoring_json(list[i]));
    nlohmann::json j = {{"pump_id", pump_id}, {"limit", limit}, {"snapshots", out}};
    if (static_cast<std::int64_t>(list.size()) > limit) j["next_since"] = storage::utc_from_ns(list.back().time_ns);
    send_json(res, 200, j);
  }

  void run(httplib::Response& res, const std::string& run_id) {
    auto h = pool.acquire();
    const auto r = h->find_run(run_id);
    if (!r) return send_error(res, 404, "no run '" + run_id + "'");
    send_json(res, 200, detail::run_json(*r, true));
  }

  // Streams the chunks from one read snapshot, so the announced length and
  // the bytes agree even while the writer adds chunks.
  void samples(httplib::Response& res, const std::string& run_id) {
    struct Download {
      detail::ReaderPool::Lease lease;
      std::optional<storage::Historian::Snapshot> snap;  // declared after: released first
    };
    auto d = std::make_shared<Download>(Download{pool.acquire(), std::nullopt});
    d->snap.emplace(d->lease->snapshot());
    const auto r = d->lease->find_run(run_id);
    if (!r) return send_error(res, 404, "no run '" + run_id + "'");
    res.status = 200;
    res.set_header("X-Run-Status", storage::to_string(r->status));
    // No chunk yet (a run just begun): an empty body with Content-Length 0.
    // httplib takes a provider of length 0 as "length unknown": it would
    // call ours again and again at offset 0 (nothing written, never done)
    // and the client would wait for its read timeout.
    if (r->samples_bytes() == 0) {
      res.set_content("", "application/octet-stream");
      return;
    }
    res.set_content_provider(
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
  http.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr ep) {
    try {
      std::rethrow_exception(ep);
    } catch (const InputError& e) {
      send_error(res, 400, e.what());
    } catch (const NotFoundError& e) {
      send_error(res, 404, e.what());
    } catch (const ConflictError& e) {
      send_error(res, 409, e.what());
    } catch (const std::exception& e) {
      send_error(res, 500, std::string("internal error: ") + e.what());
    } catch (...) {
      send_error(res, 500, "internal error");
    }
  });
  // httplib's own refusals (malformed request line, too long URI, ...) as JSON too.
  http.set_error_handler([](const httplib::Request&, httplib::Response& res) {
    if (res.body.empty()) send_error(res, res.status, "HTTP " + std::to_string(res.status));
  });
}

RestServer::~RestServer() { stop(); }

int RestServer::start() {
  auto& o = impl_->opt;
  if (impl_->thread.joinable()) return impl_->port;
  const int port = o.port == 0 ? impl_->http.bind_to_any_port(o.host) : (impl_->http.bind_to_port(o.host, o.port) ? o.port : -1);
  if (port <= 0) throw InputError("REST: cannot listen on " + o.host + ":" + std::to_string(o.port));
  impl_->port = port;
  impl_->thread = std::thread([this] { impl_->http.listen_after_bind(); });
  return port;
}

void RestServer::stop() {
  if (!impl_ || !impl_->thread.joinable()) return;
  impl_->http.stop();
  impl_->thread.join();
}

int RestServer::port() const { return impl_->port; }

}  // namespace ambdiag::server
