// Fuzz target for the request parsing that is ours (server/src/url.h,
// routes/route_table.h): a request target split into percent-decoded path
// segments (the query and fragment cut off), and the route a method and
// those segments reach. httplib parses the request line and the query
// string's parameters; what we do with the target is fuzzed here.
//
// Input: "METHOD TARGET", optionally preceded by a line "+PATTERN" that is
// added to the table first (malformed patterns must be refused with
// std::logic_error, never accepted half-parsed). Invariants, each a
// __builtin_trap when broken:
//   - decoding is the inverse of url_encode_segment;
//   - the query and fragment do not change the segments;
//   - segments encoded again and split give the same segments;
//   - a route found has every parameter of its pattern, non-empty, and the
//     path rebuilt from them reaches the same route with the same values.
// Rule JSON (alarm rules) is fuzzed with the alarm side.
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "ambdiag/server/rest_server.h"
#include "routes/route_table.h"
#include "url.h"

namespace {

using ambdiag::server::url_encode_segment;
using namespace ambdiag::server::detail;

void check(bool ok) {
  if (!ok) __builtin_trap();
}

// The shapes of the server's patterns: literals, {name}, a {name*} at the
// end and in the middle, two parameters, several methods on one path.
RouteTable base_table() {
  RouteTable t;
  const auto noop = [](RouteContext&, const PathParams&) {};
  for (const char* p :
       {"/api/v1/health", "/metrics", "/api/v1/pumps", "/api/v1/pumps/{pump_id}",
        "/api/v1/pumps/{pump_id}/model", "/api/v1/pumps/{pump_id}/trends", "/api/v1/runs/{run_id*}",
        "/api/v1/runs/{run_id*}/analysis", "/api/v1/runs/{run_id*}/samples.f32",
        "/api/v1/jobs/{job_id}/files/{name}", "/api/v1/alarms/{alarm_id}/ack"})
    t.add({"GET", p, std::nullopt, "", noop});
  t.add({"PUT", "/api/v1/pumps/{pump_id}/model", std::nullopt, "", noop});
  t.add({"POST", "/api/v1/alarms/{alarm_id}/ack", std::nullopt, "", noop});
  return t;
}

// The path a route's pattern gives with these parameter values, each
// segment encoded (a {name*} value as one segment, '/' as %2F, as clients
// send a run_id).
std::string rebuild(const std::vector<PatternSegment>& pattern, const PathParams& params) {
  std::string path;
  for (const auto& s : pattern) path += "/" + url_encode_segment(s.param ? params.at(s.text) : s.text);
  return path;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  RouteTable table = base_table();
  const size_t base_routes = table.routes().size();
  if (!text.empty() && text[0] == '+') {
    const size_t nl = text.find('\n');
    const std::string pattern = text.substr(1, nl == std::string::npos ? std::string::npos : nl - 1);
    text = nl == std::string::npos ? "" : text.substr(nl + 1);
    try {
      table.add({"GET", pattern, std::nullopt, "", [](RouteContext&, const PathParams&) {}});
    } catch (const std::logic_error&) {
    }
  }
  const size_t sp = text.find(' ');
  const std::string method = sp == std::string::npos ? "GET" : text.substr(0, sp);
  const std::string target = sp == std::string::npos ? text : text.substr(sp + 1);

  if (const auto d = url_decode_segment(url_encode_segment(target)))
    check(*d == target);
  else
    check(false);

  const auto segments = split_path(target);
  if (!segments) return 0;  // refused: 400
  const std::string path = target.substr(0, target.find_first_of("?#"));
  check(split_path(path) == segments);
  check(split_path(path + "?x=%zz&y#frag") == segments);
  std::string again;
  for (const auto& s : *segments) again += "/" + url_encode_segment(s);
  check(split_path(again) == segments);

  const auto found = table.find(method, *segments);
  if (!found.route) {
    check(found.route == nullptr && (found.path_known || found.allow.empty()));
    return 0;
  }
  check(found.path_known);
  const auto& routes = table.routes();
  const size_t index = static_cast<size_t>(found.route - routes.data());
  check(index < routes.size());
  const auto& pattern = table.pattern(index);
  for (const auto& s : pattern)
    if (s.param) check(found.params.count(s.text) == 1 && !found.params.at(s.text).empty());
  // An added pattern may be as specific as one of the table's (the table
  // takes the first then): the round trip is checked on the server's shapes.
  if (table.routes().size() != base_routes) return 0;
  const auto rebuilt = split_path(rebuild(pattern, found.params));
  check(rebuilt.has_value());
  const auto same = table.find(method, *rebuilt);
  check(same.route == found.route && same.params == found.params);
  return 0;
}
