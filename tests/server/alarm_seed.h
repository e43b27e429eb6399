// An active, unacknowledged alarm of a pump, stored as the server's alarm
// evaluator stores one (with its raise in the journal): for the tests of
// the alarm routes, which need an alarm without analysing a faulty run.
// `latched`: it reached its rule's latch severity (an engineer resets it).
#pragma once

#include <cstdint>
#include <string>

#include "../storage/historian_fixture.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::server {

inline std::int64_t seed_alarm(storage::Historian& h, const std::string& pump_id, const std::string& rule,
                               const std::string& run_id, bool latched = false) {
  storage::AlarmChanges c;
  c.pump_id = pump_id;
  storage::AlarmRecord a = ambdiag::testing::open_alarm(pump_id, rule);
  a.run_id = run_id;
  a.message = "balance_piston_wear: clearance_factor 1.7";
  a.latched = latched;
  c.alarms.push_back(a);
  c.events.emplace_back(
      0, storage::AlarmEvent{0, 0, "", "", "raise", a.raised_at, "normal", "unack_active", "server", "", a.run_id});
  h.apply_alarm_changes(c);
  return c.alarms[0].alarm_id;
}

}  // namespace ambdiag::server
