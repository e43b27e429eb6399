// What the trend routes (trend_routes.cc) and the Grafana data source
// (grafana_routes.cc) share: the series' JSON with its reference band and
// limits, and the time parameters.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

// {"name", "unit", "count", "points": [...], "truncated", "next_from"?,
// "bucket_s"?}: points {"time", "value", "sd"?, "run_id"?} (run_id for
// series fed by runs), or buckets {"time", "min", "max", "first", "last",
// "count"}, oldest first.
nlohmann::json trend_json(const storage::Trend& t);

// {"mean", "sd", "runs", "version"}: the series over the pump's current
// reference runs (each run's newest analysis), sd with n - 1 (absent for a
// single run); nullopt when the pump has no reference or its runs give the
// series no value (monitoring series: no runs).
std::optional<nlohmann::json> reference_band(storage::Historian& h, const std::string& pump_id, const std::string& series);

// The limits a chart draws for the series: the pump's effective alarm rule
// that watches it (alarms/alarm_limits.h), with `defaults` the server's
// default rules and `reference` the series' reference band; nullopt (the
// "limits" key left out) where no enabled rule watches the series.
std::optional<nlohmann::json> series_limits(storage::Historian& h, const std::string& pump_id, const std::string& series,
                                            const nlohmann::json& defaults, const std::optional<nlohmann::json>& reference);

// Seconds since the epoch as ISO 8601 UTC; nullopt outside what an int64 of
// ns holds (1677..2262).
std::optional<std::string> utc_from_s(double t_s);

}  // namespace ambdiag::server::detail
