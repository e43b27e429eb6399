#include "rest_json.h"

#include <cstdio>

#include "ambdiag/server/rest_server.h"

namespace ambdiag::server::detail {

nlohmann::json pump_json(const storage::PumpSummary& p) {
  nlohmann::json j = {{"pump_id", p.pump_id}, {"n_runs", p.n_runs}};
  if (!p.last_run_id.empty()) {
    j["last_run_id"] = p.last_run_id;
    j["last_started_at"] = p.last_started_at;
  }
  return j;
}

nlohmann::json run_json(const storage::RunInfo& r, bool with_header) {
  nlohmann::json j = {{"run_id", r.run_id},
                      {"pump_id", r.pump_id},
                      {"kind", r.kind},
                      {"started_at", r.started_at},
                      {"speed_rpm", r.speed_rpm},
                      {"sample_rate_hz", r.sample_rate_hz},
                      {"n_channels", r.n_channels},
                      {"status", storage::to_string(r.status)},
                      {"received_chunks", r.received_chunks},
                      {"received_frames", r.received_frames},
                      {"duplicate_chunks", r.duplicate_chunks},
                      {"samples_bytes", r.samples_bytes()},
                      {"samples_url", "/api/v1/runs/" + url_encode_segment(r.run_id) + "/samples.f32"},
                      {"created_at", r.created_at},
                      {"updated_at", r.updated_at}};
  if (!r.status_reason.empty()) j["status_reason"] = r.status_reason;
  if (r.expected_frames) j["expected_frames"] = *r.expected_frames;
  if (r.expected_checksum) {
    char buf[24];  // hex string: JSON numbers lose 64-bit precision in many clients
    std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(*r.expected_checksum));
    j["expected_checksum"] = buf;
    if (r.checksum_kind) j["checksum_kind"] = to_string(*r.checksum_kind);
  }
  if (r.ended_at) j["ended_at"] = *r.ended_at;
  // Retention (docs/storage.md): what is still held of the run.
  j["samples"] = r.samples_dropped_at ? "dropped" : "held";
  if (r.samples_dropped_at) {
    j["samples_dropped_at"] = *r.samples_dropped_at;
    j["samples_dropped_bytes"] = r.samples_dropped_bytes;
  }
  if (r.frf_dropped_at) {
    j["frf_dropped_at"] = *r.frf_dropped_at;
    j["frf_dropped_bytes"] = r.frf_dropped_bytes;
  }
  if (with_header) j["header"] = nlohmann::json::parse(r.header_json);
  return j;
}

nlohmann::json monitoring_json(const storage::MonitoringSnapshot& s) {
  const auto planes = [](const std::array<double, 4>& v) {
    return nlohmann::json{{"ax", v[0]}, {"ay", v[1]}, {"bx", v[2]}, {"by", v[3]}};
  };
  const auto bearing = [&](size_t i) {
    return nlohmann::json{{"major_m", s.orbit_major_m[i]},
                          {"minor_m", s.orbit_minor_m[i]},
                          {"center_x_m", s.orbit_center_x_m[i]},
                          {"center_y_m", s.orbit_center_y_m[i]}};
  };
  return {{"time", storage::utc_from_ns(s.time_ns)},
          {"time_ns", std::to_string(s.time_ns)},
          {"speed_rpm", s.speed_rpm},
          {"force_1x", {{"amp_n", planes(s.force_1x_amp_n)}, {"phase_rad", planes(s.force_1x_phase_rad)}}},
          {"force_2x", {{"amp_n", planes(s.force_2x_amp_n)}, {"phase_rad", planes(s.force_2x_phase_rad)}}},
          {"orbit", {{"a", bearing(0)}, {"b", bearing(1)}}}};
}

std::string dump(const nlohmann::json& j) { return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace); }

}  // namespace ambdiag::server::detail
