#include "ambdiag/server/rest_server.h"

#include <httplib.h>

#include <chrono>
#include <optional>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "reader_pool.h"
#include "routes/route_context.h"
#include "url.h"

namespace ambdiag::server {

using detail::send_error;

struct RestServer::Impl {
  RestOptions opt;
  detail::ReaderPool pool;
  detail::RouteTable routes;
  httplib::Server http;
  std::thread thread;
  int port = 0;

  explicit Impl(RestOptions o) : opt(std::move(o)), pool(opt.db_path, std::max(1, opt.worker_threads)) {
    detail::add_read_routes(routes, std::chrono::steady_clock::now());
    detail::add_analysis_routes(routes);
    detail::add_alarm_routes(routes);
  }

  void handle(const httplib::Request& req, httplib::Response& res) {
    const auto segments = detail::split_path(req.target);
    if (!segments) return send_error(res, 400, "bad path or percent-encoding: " + req.target);
    const auto found = routes.find(req.method, *segments);
    if (!found.route) {
      if (!found.path_known) return send_error(res, 404, "no such resource: " + req.path);
      res.set_header("Allow", found.allow);
      return send_error(res, 405, req.method + " not allowed on " + req.path + " (allowed: " + found.allow + ")");
    }
    const detail::Route& route = *found.route;
    std::optional<detail::Caller> caller;
    if (route.role) {
      caller = detail::authorize(pool, req, *route.role, opt.anonymous_read, res);
      if (!caller) return;  // 401 or 403 sent
    }
    if (route.method != "GET" && !opt.analysis)
      return send_error(res, 503, "this server runs without the analysis service: " + req.method + " " + req.path + " is not served");
    detail::RouteContext ctx{pool, opt, caller.value_or(detail::Caller{}), req, res};
    route.handler(ctx, found.params);
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
