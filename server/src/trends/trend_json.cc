#include "trends/trend_json.h"

#include <cmath>

#include "alarms/alarm_evaluator.h"
#include "alarms/alarm_limits.h"

namespace ambdiag::server::detail {

using nlohmann::json;

json trend_json(const storage::Trend& t) {
  json points = json::array();
  for (const auto& p : t.points) {
    json j = {{"time", storage::utc_from_ns(p.time_ns)}, {"value", p.value}};
    if (p.sd) j["sd"] = *p.sd;
    if (!p.run_id.empty()) j["run_id"] = p.run_id;
    points.push_back(std::move(j));
  }
  for (const auto& b : t.buckets)
    points.push_back({{"time", storage::utc_from_ns(b.time_ns)},
                      {"min", b.min},
                      {"max", b.max},
                      {"first", b.first},
                      {"last", b.last},
                      {"count", b.count}});
  json j = {{"name", t.series.name}, {"unit", t.series.unit}, {"count", t.count}, {"points", points}, {"truncated", t.truncated}};
  if (t.next_from_ns) j["next_from"] = storage::utc_from_ns(*t.next_from_ns);
  if (t.bucket_ns > 0) j["bucket_s"] = 1e-9 * static_cast<double>(t.bucket_ns);
  return j;
}

std::optional<json> reference_band(storage::Historian& h, const std::string& pump_id, const std::string& series) {
  const auto ref = h.find_reference(pump_id);
  if (!ref) return std::nullopt;
  const auto points = h.run_points(pump_id, series, ref->run_ids);
  if (points.empty()) return std::nullopt;
  double mean = 0;
  for (const auto& p : points) mean += p.value;
  mean /= static_cast<double>(points.size());
  json j = {{"mean", mean}, {"runs", points.size()}, {"version", ref->version}};
  if (points.size() > 1) {
    double ss = 0;
    for (const auto& p : points) ss += (p.value - mean) * (p.value - mean);
    j["sd"] = std::sqrt(ss / static_cast<double>(points.size() - 1));
  }
  return j;
}

std::optional<json> series_limits(storage::Historian& h, const std::string& pump_id, const std::string& series, const json& defaults,
                                  const std::optional<json>& reference) {
  return alarm_limits(pump_rule_set(h, pump_id, defaults), series, reference);
}

std::optional<std::string> utc_from_s(double t_s) {
  if (!std::isfinite(t_s) || std::fabs(t_s) > 9.2e9) return std::nullopt;
  return storage::utc_from_ns(static_cast<std::int64_t>(std::llround(t_s * 1e9)));
}

}  // namespace ambdiag::server::detail
