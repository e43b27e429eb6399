#include <nlohmann/json.hpp>

#include "ambdiag/core/error.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::storage {

std::string to_string(RunStatus s) {
  switch (s) {
    case RunStatus::receiving: return "receiving";
    case RunStatus::complete: return "complete";
    case RunStatus::incomplete: return "incomplete";
  }
  return "receiving";
}

RunHeader run_header_from_json(const std::string& run_json_text, const std::string& source) {
  RunRecording rec;
  try {
    nlohmann::json doc;
    try {
      doc = nlohmann::json::parse(run_json_text);
    } catch (const nlohmann::json::parse_error& e) {
      throw InputError(std::string("not JSON: ") + e.what());
    }
    rec = run_from_json(doc);
  } catch (const InputError& e) {
    rethrow_with_context(e, source);
  }
  RunHeader h;
  h.run_id = rec.run_id;
  h.pump_id = rec.pump_id;
  h.kind = rec.kind;
  h.started_at = rec.started_at;
  h.speed_rpm = rec.speed_rpm;
  h.sample_rate_hz = rec.sample_rate_hz;
  for (const auto& c : rec.channels) h.channels.push_back({c.name, c.role_text.empty() ? to_string(c.role) : c.role_text, c.unit, c.input});
  h.header_json = run_json_text;
  return h;
}

}  // namespace ambdiag::storage
