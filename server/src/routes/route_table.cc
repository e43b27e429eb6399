#include "routes/route_table.h"

#include <stdexcept>

namespace ambdiag::server::detail {

namespace {

std::vector<PatternSegment> parse(const std::string& pattern) {
  if (pattern.empty() || pattern[0] != '/') throw std::logic_error("route pattern must start with '/': " + pattern);
  if (pattern == "/") return {{"", false, false}};  // the root: split_path("/") is one empty segment
  std::vector<PatternSegment> out;
  int rests = 0;
  size_t pos = 1;
  while (pos <= pattern.size()) {
    const size_t end = std::min(pattern.find('/', pos), pattern.size());
    const std::string s = pattern.substr(pos, end - pos);
    if (s.empty()) throw std::logic_error("empty segment in route pattern " + pattern);
    if (s.front() == '{') {
      if (s.back() != '}' || s.size() < 3) throw std::logic_error("bad parameter in route pattern " + pattern);
      const bool rest = s[s.size() - 2] == '*';
      out.push_back({s.substr(1, s.size() - (rest ? 3 : 2)), true, rest});
      rests += rest;
    } else {
      out.push_back({s, false, false});
    }
    pos = end + 1;
  }
  if (rests > 1) throw std::logic_error("more than one {name*} in route pattern " + pattern);
  return out;
}

// Matches, filling `params`; the literal count is the match's specificity.
bool matches(const std::vector<PatternSegment>& pattern, const std::vector<std::string>& path, PathParams& params) {
  size_t star = pattern.size();
  for (size_t i = 0; i < pattern.size(); ++i)
    if (pattern[i].rest) star = i;
  const auto one = [&](const PatternSegment& p, const std::string& s) {
    if (p.param) {
      if (s.empty()) return false;
      params[p.text] = s;
      return true;
    }
    return p.text == s;
  };
  if (star == pattern.size()) {
    if (path.size() != pattern.size()) return false;
    for (size_t i = 0; i < path.size(); ++i)
      if (!one(pattern[i], path[i])) return false;
    return true;
  }
  const size_t after = pattern.size() - star - 1;
  if (path.size() < star + 1 + after) return false;
  for (size_t i = 0; i < star; ++i)
    if (!one(pattern[i], path[i])) return false;
  for (size_t i = 0; i < after; ++i)
    if (!one(pattern[star + 1 + i], path[path.size() - after + i])) return false;
  std::string joined;
  for (size_t i = star; i < path.size() - after; ++i) {
    if (path[i].empty()) return false;
    joined += (i > star ? "/" : "") + path[i];
  }
  params[pattern[star].text] = joined;
  return true;
}

int literals(const std::vector<PatternSegment>& pattern) {
  int n = 0;
  for (const auto& s : pattern) n += !s.param;
  return n;
}

}  // namespace

Route& RouteTable::add(Route r) {
  if (r.method != "GET" && r.method != "POST" && r.method != "PUT")
    throw std::logic_error("route method must be GET, POST or PUT: " + r.method);
  auto pattern = parse(r.pattern);
  for (const auto& o : routes_)
    if (o.method == r.method && o.pattern == r.pattern) throw std::logic_error("route added twice: " + r.method + " " + r.pattern);
  if (!r.handler) throw std::logic_error("route without handler: " + r.pattern);
  routes_.push_back(std::move(r));
  patterns_.push_back(std::move(pattern));
  return routes_.back();
}

void RouteTable::add_schema(const std::string& name, nlohmann::json schema) {
  if (!schemas_.emplace(name, std::move(schema)).second) throw std::logic_error("schema added twice: " + name);
}

RouteTable::Found RouteTable::find(const std::string& method, const std::vector<std::string>& segments) const {
  const std::string m = method == "HEAD" ? "GET" : method;
  Found best;
  int best_score = -1;
  std::vector<std::string> methods;  // of the best-scoring pattern
  for (size_t i = 0; i < routes_.size(); ++i) {
    const Route& r = routes_[i];
    const auto& pattern = patterns_[i];
    PathParams params;
    if (!matches(pattern, segments, params)) continue;
    const int score = literals(pattern);
    if (score < best_score) continue;
    if (score > best_score) {
      best = Found{};
      best_score = score;
      methods.clear();
    }
    best.path_known = true;
    methods.push_back(r.method);
    if (r.method == m && !best.route) {
      best.route = &r;
      best.params = std::move(params);
    }
  }
  for (const char* each : {"GET", "POST", "PUT"})
    for (const auto& x : methods)
      if (x == each) {
        best.allow += std::string(best.allow.empty() ? "" : ", ") + each + (x == "GET" ? ", HEAD" : "");
        break;
      }
  if (!best.route && segments.size() > 1 && segments.back().empty()) {
    auto trimmed = find(method, {segments.begin(), segments.end() - 1});
    if (trimmed.route && trimmed.route->trailing_slash) return trimmed;
  }
  return best;
}

}  // namespace ambdiag::server::detail
