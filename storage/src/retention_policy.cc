// Retention policies as JSON (retention.h): parsing with the field named,
// and the sweep's report.
#include <cmath>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/storage/retention.h"

namespace ambdiag::storage {

namespace {

using nlohmann::json;

constexpr double kMaxDays = 36500;                       // a century: "for ever" is null
constexpr double kMaxBytes = 4611686018427387904.0;      // 2^62

std::string known_keys() {
  std::string s;
  for (const char* k : kRetentionKeys) s += (s.empty() ? "" : ", ") + std::string(k);
  return s;
}

std::optional<double> days_of(const json& v, const std::string& where) {
  if (v.is_null()) return std::nullopt;
  if (!v.is_number() || !std::isfinite(v.get<double>()) || v.get<double>() < 0 || v.get<double>() > kMaxDays)
    throw InputError(where + ": must be a number of days in 0.." + std::to_string(static_cast<int>(kMaxDays)) +
                     ", or null to keep for ever (got " + v.dump() + ")");
  return v.get<double>();
}

std::optional<std::int64_t> bytes_of(const json& v, const std::string& where) {
  if (v.is_null()) return std::nullopt;
  const bool ok = v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() >= 0 &&
                  v.get<double>() <= kMaxBytes && std::floor(v.get<double>()) == v.get<double>();
  if (!ok) throw InputError(where + ": must be a whole number of bytes in 0..2^62, or null for no limit (got " + v.dump() + ")");
  return v.is_number_integer() ? v.get<std::int64_t>() : static_cast<std::int64_t>(v.get<double>());
}

}  // namespace

RetentionPolicy retention_policy_from_json(const json& j, const RetentionPolicy& base, const std::string& source) {
  if (!j.is_object())
    throw InputError(source + ": must be a JSON object of " + known_keys() + " (got " + std::string(j.type_name()) + ")");
  RetentionPolicy p = base;
  for (const auto& [key, v] : j.items()) {
    const std::string where = source + ": " + key;
    if (key == "samples_days")
      p.samples_days = days_of(v, where);
    else if (key == "samples_bytes")
      p.samples_bytes = bytes_of(v, where);
    else if (key == "frf_days")
      p.frf_days = days_of(v, where);
    else if (key == "monitoring_days")
      p.monitoring_days = days_of(v, where);
    else
      throw InputError(where + ": unknown key (known: " + known_keys() + ")");
  }
  return p;
}

json to_json(const RetentionPolicy& p) {
  const auto opt = [](const auto& v) { return v ? json(*v) : json(nullptr); };
  return {{"samples_days", opt(p.samples_days)},
          {"samples_bytes", opt(p.samples_bytes)},
          {"frf_days", opt(p.frf_days)},
          {"monitoring_days", opt(p.monitoring_days)}};
}

json to_json(const SweepReport& r, bool with_runs) {
  json j = {{"dry_run", r.dry_run},
            {"stopped", r.stopped},
            {"pumps", r.pumps},
            {"samples", {{"runs", r.samples_runs}, {"bytes", r.samples_bytes}}},
            {"frf", {{"runs", r.frf_runs}, {"bytes", r.frf_bytes}}},
            {"monitoring_rows", r.monitoring_rows},
            {"partitions", r.partitions},
            {"moved", {{"runs", r.moved_runs}, {"bytes", r.moved_bytes}}},
            {"transactions", r.transactions},
            {"transactions_s", r.transactions_s},
            {"longest_transaction_s", r.longest_transaction_s},
            {"seconds", r.seconds},
            {"errors", r.errors}};
  if (!r.skipped.empty()) j["skipped"] = r.skipped;
  if (with_runs) {
    json runs = json::array();
    for (const auto& s : r.runs)
      runs.push_back({{"run_id", s.run_id}, {"pump_id", s.pump_id}, {"what", s.what}, {"bytes", s.bytes}, {"reason", s.reason}});
    j["runs"] = runs;
  }
  return j;
}

}  // namespace ambdiag::storage
