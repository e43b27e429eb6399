// Fuzz target: a pump's alarm rules as PUT over REST (server/src/alarms/
// alarm_rules.h), merged over the built-in defaults. Only InputError may
// escape; a rule set that was accepted must survive its own round trip.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "alarms/alarm_rules.h"
#include "ambdiag/core/error.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace ambdiag::server::detail;
  static const nlohmann::json defaults = default_rule_set_json();
  const std::string text(reinterpret_cast<const char*>(data), size);
  const nlohmann::json doc = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded()) return 0;
  try {
    const AlarmRuleSet s = merge_rule_sets(defaults, doc, "");
    if (rule_set_from_json(s.to_json(), "").to_json() != s.to_json()) __builtin_trap();
  } catch (const ambdiag::InputError&) {
  }
  return 0;
}
