// The read side's answers (cli.md "REST", rest_json.h).
#include "routes/api_schemas.h"

namespace ambdiag::server::detail {

using namespace schema;

void add_read_schemas(RouteTable& t) {
  t.add_schema("Health", object({{"status", one_of({"ok"})},
                                 {"service", string()},
                                 {"version", string()},
                                 {"schema_version", integer()},
                                 {"runs", integer()},
                                 {"uptime_s", number()}},
                                // what `ambdiag serve` adds (RestOptions::health_extra)
                                {{"instance", string()},
                                 {"parts", array(string())},
                                 {"ingest", nullable(object({}))},
                                 {"jobs", nullable(object({}))},
                                 {"checkpoints", object({})}}));
  t.add_schema("PumpSummary", object({{"pump_id", string()}, {"n_runs", integer()}},
                                     {{"last_run_id", string()}, {"last_started_at", time()}}));
  t.add_schema("Run", object({{"run_id", string()},
                              {"pump_id", string()},
                              {"kind", string()},
                              {"started_at", time()},
                              {"speed_rpm", number()},
                              {"sample_rate_hz", number()},
                              {"n_channels", integer()},
                              {"status", one_of({"receiving", "complete", "incomplete"})},
                              {"received_chunks", integer()},
                              {"received_frames", integer()},
                              {"duplicate_chunks", integer()},
                              {"samples_bytes", integer()},
                              {"samples_url", string()},
                              {"created_at", time()},
                              {"updated_at", time()},
                              {"samples", one_of({"held", "dropped"})}},
                             {{"status_reason", string()},
                              {"expected_frames", integer()},
                              {"expected_checksum", string()},
                              {"checksum_kind", string()},
                              {"ended_at", time()},
                              {"samples_dropped_at", time()},
                              {"samples_dropped_bytes", integer()},
                              {"frf_dropped_at", time()},
                              {"frf_dropped_bytes", integer()},
                              {"header", object({})}}));
  const json planes = object({{"ax", number()}, {"ay", number()}, {"bx", number()}, {"by", number()}});
  const json force = object({{"amp_n", planes}, {"phase_rad", planes}});
  const json orbit = object({{"major_m", number()}, {"minor_m", number()}, {"center_x_m", number()}, {"center_y_m", number()}});
  t.add_schema("MonitoringSnapshot", object({{"time", time()},
                                             {"time_ns", string()},
                                             {"speed_rpm", number()},
                                             {"force_1x", force},
                                             {"force_2x", force},
                                             {"orbit", object({{"a", orbit}, {"b", orbit}})}}));
}

}  // namespace ambdiag::server::detail
