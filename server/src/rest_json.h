// JSON bodies of the REST responses.
#pragma once

#include <nlohmann/json.hpp>

#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

nlohmann::json pump_json(const storage::PumpSummary& p);
// `with_header`: the run.json content as an object under "header".
nlohmann::json run_json(const storage::RunInfo& r, bool with_header);
// {"time", "time_ns" (decimal string: 64 bits), "speed_rpm", "force_1x":
// {"amp_n": {"ax", "ay", "bx", "by"}, "phase_rad": {...}}, "force_2x": {...},
// "orbit": {"a": {"major_m", "minor_m", "center_x_m", "center_y_m"}, "b": {...}}}
nlohmann::json monitoring_json(const storage::MonitoringSnapshot& s);
// Never throws on odd bytes (invalid UTF-8 from a request path is replaced).
std::string dump(const nlohmann::json& j);

}  // namespace ambdiag::server::detail
