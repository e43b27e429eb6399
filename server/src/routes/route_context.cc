#include "routes/route_context.h"

#include "ambdiag/core/error.h"
#include "rest_json.h"

namespace ambdiag::server::detail {

std::int64_t positive_integer(const std::string& text, const std::string& what) {
  if (text.empty() || text.size() > 15 || text.find_first_not_of("0123456789") != std::string::npos || std::stoll(text) < 1)
    throw InputError(what + ": '" + text + "' is not a positive integer");
  return std::stoll(text);
}

nlohmann::json parse_body(const httplib::Request& req, const std::string& what) {
  try {
    return nlohmann::json::parse(req.body);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(what + ": the body is not JSON: " + e.what());
  }
}

void send_json(httplib::Response& res, int status, const nlohmann::json& body) {
  res.status = status;
  res.set_content(dump(body), "application/json");
}

void send_error(httplib::Response& res, int status, const std::string& message) {
  send_json(res, status, {{"error", message}});
}

std::optional<Caller> authorize(ReaderPool& pool, const httplib::Request& req, storage::Role needed, bool anonymous_read,
                                httplib::Response& res, bool token_in_query) {
  std::string header = req.get_header_value("Authorization");
  if (header.empty() && token_in_query && req.has_param("access_token")) header = "Bearer " + req.get_param_value("access_token");
  std::optional<Caller> caller;
  if (header.empty()) {
    if (anonymous_read) caller = Caller{};
  } else {
    constexpr std::string_view kBearer = "Bearer ";
    if (header.size() <= kBearer.size() || header.compare(0, kBearer.size(), kBearer) != 0) {
      res.set_header("WWW-Authenticate", "Bearer");
      send_error(res, 401, "Authorization: expected 'Bearer TOKEN'");
      return std::nullopt;
    }
    auto h = pool.acquire();
    if (const auto t = h->find_token(header.substr(kBearer.size()))) caller = Caller{t->name, t->role, true};
    if (!caller) {
      res.set_header("WWW-Authenticate", "Bearer error=\"invalid_token\"");
      send_error(res, 401, "unknown or revoked token");
      return std::nullopt;
    }
  }
  if (!caller) {
    res.set_header("WWW-Authenticate", "Bearer");
    send_error(res, 401, "this request needs a token (Authorization: Bearer TOKEN; ambdiag token add)");
    return std::nullopt;
  }
  if (static_cast<int>(caller->role) < static_cast<int>(needed)) {
    send_error(res, 403, "role '" + storage::to_string(caller->role) + "' of '" + caller->name + "' is too low: " + req.method +
                             " " + req.path + " needs '" + storage::to_string(needed) + "'");
    return std::nullopt;
  }
  return caller;
}

}  // namespace ambdiag::server::detail
