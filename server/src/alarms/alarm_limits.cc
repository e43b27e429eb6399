#include "alarms/alarm_limits.h"

#include <algorithm>
#include <cmath>
#include <functional>

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// Lines of `rule` with each level and the clear limit mapped by `to_series`
// (rule value -> series values: one, or two for a two-sided rule).
json lines_of(const AlarmRule& rule, const std::function<std::vector<double>(double)>& to_series) {
  json lines = json::array();
  for (const auto& l : rule.levels)
    for (double v : to_series(l.raise)) lines.push_back({{"kind", "raise"}, {"severity", to_string(l.severity)}, {"value", v}});
  for (double v : to_series(rule.clear)) lines.push_back({{"kind", "clear"}, {"value", v}});
  return {{"rule", rule.id}, {"lines", lines}};
}

}  // namespace

std::optional<json> alarm_limits(const AlarmRuleSet& rules, const std::string& series, const std::optional<json>& reference) {
  const auto one = [](double v) { return std::vector<double>{v}; };
  if (series == "detection.ratio") {
    const AlarmRule* r = rules.find("detection");
    if (!r || !r->enabled) return std::nullopt;
    return lines_of(*r, one);
  }
  if (series == "fit.nrmse") {
    const AlarmRule* r = rules.find("poor_data");
    if (!r || !r->enabled) return std::nullopt;
    return lines_of(*r, [&](double v) { return std::vector<double>{v * r->nrmse_limit}; });
  }
  if (series.rfind("fault.", 0) == 0) {
    const size_t dot = series.rfind('.');
    if (dot <= 6) return std::nullopt;
    const AlarmRule* r = rules.find(series.substr(0, dot));
    if (!r || !r->enabled || r->parameter != series.substr(dot + 1)) return std::nullopt;
    if (!r->nominal) return lines_of(*r, one);
    const double nom = *r->nominal;
    return lines_of(*r, [nom](double v) { return std::vector<double>{nom + v, nom - v}; });
  }
  if (series.rfind("mode.", 0) == 0 && (ends_with(series, ".f_hz") || ends_with(series, ".zeta"))) {
    const AlarmRule* r = rules.find(series);
    if (!r || !r->enabled || !reference || !reference->contains("mean")) return std::nullopt;
    const double mean = (*reference)["mean"].get<double>();
    const double sd = reference->value("sd", 0.0);
    if (!(std::abs(mean) > 0)) return std::nullopt;
    // value = |x / mean - 1| / max(min shift, k_sd sd / mean)
    const double scale = std::max(r->min_relative_shift, r->k_sd * sd / std::abs(mean));
    return lines_of(*r, [mean, scale](double v) { return std::vector<double>{mean * (1 + v * scale), mean * (1 - v * scale)}; });
  }
  return std::nullopt;
}

}  // namespace ambdiag::server::detail
