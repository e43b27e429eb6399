#include "alarms/alarm_kpis.h"

#include <algorithm>
#include <map>

#include "alarms/alarm_state.h"
#include "ambdiag/core/error.h"
#include "ambdiag/storage/monitoring.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

constexpr std::int64_t kTenMinutesNs = 600'000'000'000LL;
constexpr std::int64_t kChatterWindowNs = 60'000'000'000LL;
constexpr int kChatterRaises = 3;
constexpr int kFloodRaises = 10;  // more than this in 10 minutes
constexpr std::int64_t kStaleNs = 24 * 3600'000'000'000LL;

}  // namespace

json alarm_kpis(const std::vector<storage::AlarmEvent>& events, const std::vector<storage::AlarmRecord>& active,
                std::int64_t from_ns, std::int64_t to_ns) {
  if (to_ns <= from_ns) throw InputError("to: must be after from");
  const std::int64_t n_buckets = (to_ns - from_ns + kTenMinutesNs - 1) / kTenMinutesNs;
  std::map<std::int64_t, int> buckets;
  std::map<std::pair<std::string, std::string>, std::vector<std::int64_t>> raises;  // (pump, rule) -> times
  int total = 0;
  for (const auto& e : events) {
    if (e.kind != "raise") continue;
    const std::int64_t t = storage::ns_from_utc(e.time, "journal time");
    ++buckets[(t - from_ns) / kTenMinutesNs];
    raises[{e.pump_id, e.rule}].push_back(t);
    ++total;
  }
  int peak = 0, flood = 0;
  for (const auto& [b, n] : buckets) {
    peak = std::max(peak, n);
    flood += n > kFloodRaises ? 1 : 0;
  }
  json chattering = json::array();
  std::vector<std::pair<int, std::pair<std::string, std::string>>> counts;
  for (auto& [key, times] : raises) {
    std::sort(times.begin(), times.end());
    int most = 0;
    for (size_t i = 0, j = 0; j < times.size(); ++j) {
      while (times[j] - times[i] > kChatterWindowNs) ++i;
      most = std::max(most, static_cast<int>(j - i + 1));
    }
    if (most >= kChatterRaises)
      chattering.push_back({{"pump_id", key.first}, {"rule", key.second}, {"raises", times.size()}, {"most_in_60s", most}});
    counts.push_back({static_cast<int>(times.size()), key});
  }
  std::sort(counts.begin(), counts.end(), [](const auto& a, const auto& b) { return a.first != b.first ? a.first > b.first : a.second < b.second; });
  json top = json::array();
  for (size_t i = 0; i < counts.size() && i < 10; ++i)
    top.push_back({{"pump_id", counts[i].second.first},
                   {"rule", counts[i].second.second},
                   {"raises", counts[i].first},
                   {"share", total > 0 ? static_cast<double>(counts[i].first) / total : 0.0}});
  json stale = json::array();
  for (const auto& a : active) {
    if (!a.active) continue;
    const std::int64_t raised = storage::ns_from_utc(a.raised_at, "raised_at");
    if (to_ns - raised > kStaleNs)
      stale.push_back({{"alarm_id", a.alarm_id}, {"pump_id", a.pump_id}, {"rule", a.rule}, {"raised_at", a.raised_at},
                       {"active_h", 1e-9 * static_cast<double>(to_ns - raised) / 3600.0}});
  }
  return {{"from", iso_ms(from_ns)},
          {"to", iso_ms(to_ns)},
          {"raises", total},
          {"intervals_10min", n_buckets},
          {"alarms_per_10min", {{"average", static_cast<double>(total) / static_cast<double>(n_buckets)}, {"peak", peak}}},
          {"flood", {{"threshold_per_10min", kFloodRaises}, {"intervals", flood},
                     {"share_of_time", static_cast<double>(flood) / static_cast<double>(n_buckets)}}},
          {"chattering", {{"definition", "3 or more raises within 60 s"}, {"alarms", chattering}}},
          {"stale", {{"definition", "active for more than 24 h"}, {"alarms", stale}}},
          {"top", top}};
}

}  // namespace ambdiag::server::detail
