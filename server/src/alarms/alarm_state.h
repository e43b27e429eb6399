// An alarm's lifecycle after ANSI/ISA-18.2 (rest.md "Alarms"): the state an
// operator sees follows from the alarm's flags,
//
//   out_of_service  its rule is disabled (engineer)
//   shelved         an operator shelved it, until shelved_until
//   suppressed      plant-state suppression (pump stopped, speed off band)
//   unack_active    condition active, not acknowledged
//   ack_active      condition active, acknowledged
//   unack_rtn       condition returned, not acknowledged
//   normal          returned and acknowledged: the alarm is closed
//
// in that order of precedence: shelving, suppression and out-of-service
// hide the alarm while the condition goes on being tracked underneath, and
// when they end the alarm shows what the condition did meanwhile. Every
// change is one journal entry (storage::AlarmEvent) with who made it.
// Pure: no storage, no clock (the caller gives the time).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "ambdiag/storage/alarms.h"

namespace ambdiag::server::detail {

// Every state above, for the REST filter's check and the OpenAPI enum.
inline const std::vector<std::string>& alarm_states() {
  static const std::vector<std::string> states = {"normal",   "unack_active", "ack_active",    "unack_rtn",
                                                  "shelved",  "suppressed",   "out_of_service"};
  return states;
}

// Who changes an alarm, when (server clock, ISO 8601 UTC with ms) and why.
struct AlarmActor {
  std::string by = "server";
  std::string time;
  std::string comment;
  std::string run_id;
};

// The state the flags give.
std::string alarm_state_of(const storage::AlarmRecord& a);

// Applies `mutate` to `a`, recomputes its state (an alarm that becomes
// normal is closed: cleared_at), and returns the journal entry of `kind`.
storage::AlarmEvent change_alarm(storage::AlarmRecord& a, const std::string& kind, const AlarmActor& actor,
                                 const std::function<void(storage::AlarmRecord&)>& mutate);

// Operator and engineer actions. Each throws ConflictError (409) naming the
// state when it does not allow the action, InputError (400) for a bad
// argument, and changes nothing then.
storage::AlarmEvent acknowledge_alarm(storage::AlarmRecord& a, const AlarmActor& actor);
// Shelved for `minutes` (1..43200, 30 days) from actor.time; a comment is required.
storage::AlarmEvent shelve_alarm(storage::AlarmRecord& a, std::int64_t minutes, const AlarmActor& actor);
storage::AlarmEvent unshelve_alarm(storage::AlarmRecord& a, const AlarmActor& actor);
// The shelve's end (actor.time >= shelved_until): by the server.
storage::AlarmEvent expire_shelve(storage::AlarmRecord& a, const AlarmActor& actor);
// A latched alarm's reset (a comment is required); `condition_clear`: the
// condition has been beyond its clear limit for the off-delay, so the alarm
// returns at once; otherwise it follows the condition from now on.
storage::AlarmEvent reset_alarm(storage::AlarmRecord& a, bool condition_clear, const AlarmActor& actor);

// Server clock times: ISO 8601 UTC with exactly three decimals, so that the
// journal's text times sort as times.
std::string iso_ms(std::int64_t ns_since_epoch);
std::int64_t now_ns();

}  // namespace ambdiag::server::detail
