#include "alarms/alarm_state.h"

#include <chrono>
#include <ctime>

#include "ambdiag/core/error.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/storage/monitoring.h"

namespace ambdiag::server::detail {

namespace {

using storage::AlarmEvent;
using storage::AlarmRecord;

std::string alarm_ref(const AlarmRecord& a) { return "alarm " + std::to_string(a.alarm_id) + " is " + a.state; }

void require_comment(const AlarmActor& actor, const char* action) {
  if (actor.comment.find_first_not_of(" \t\r\n") == std::string::npos)
    throw InputError(std::string("comment: required to ") + action + " an alarm");
}

}  // namespace

std::string alarm_state_of(const AlarmRecord& a) {
  if (a.out_of_service) return "out_of_service";
  if (a.shelved_until) return "shelved";
  if (!a.suppressed_reason.empty() && (a.active || !a.acknowledged)) return "suppressed";
  if (a.active) return a.acknowledged ? "ack_active" : "unack_active";
  return a.acknowledged ? "normal" : "unack_rtn";
}

AlarmEvent change_alarm(AlarmRecord& a, const std::string& kind, const AlarmActor& actor,
                        const std::function<void(AlarmRecord&)>& mutate) {
  AlarmEvent e;
  e.kind = kind;
  e.time = actor.time;
  e.from = a.alarm_id == 0 && a.state.empty() ? "normal" : a.state;
  e.by = actor.by.empty() ? "server" : actor.by;
  e.comment = actor.comment;
  e.run_id = actor.run_id;
  mutate(a);
  a.state = alarm_state_of(a);
  a.updated_at = actor.time;
  if (a.state == "normal") {
    // Closed: a shelve or a suppression of a closed alarm has nothing left to hide.
    if (!a.cleared_at) a.cleared_at = actor.time;
    a.shelved_until.reset();
    a.suppressed_reason.clear();
  }
  e.to = a.state;
  return e;
}

AlarmEvent acknowledge_alarm(AlarmRecord& a, const AlarmActor& actor) {
  if (a.state != "unack_active" && a.state != "unack_rtn")
    throw ConflictError(alarm_ref(a) + ": only an unack_active or unack_rtn alarm is acknowledged");
  return change_alarm(a, "ack", actor, [](AlarmRecord& x) { x.acknowledged = true; });
}

AlarmEvent shelve_alarm(AlarmRecord& a, std::int64_t minutes, const AlarmActor& actor) {
  if (minutes < 1 || minutes > 43200) throw InputError("minutes: must be an integer in 1..43200 (30 days)");
  require_comment(actor, "shelve");
  if (a.state != "unack_active" && a.state != "ack_active" && a.state != "unack_rtn")
    throw ConflictError(alarm_ref(a) + ": only an unack_active, ack_active or unack_rtn alarm is shelved");
  const std::int64_t until = storage::ns_from_utc(actor.time, "time") + minutes * 60'000'000'000LL;
  return change_alarm(a, "shelve", actor, [&](AlarmRecord& x) { x.shelved_until = iso_ms(until); });
}

AlarmEvent unshelve_alarm(AlarmRecord& a, const AlarmActor& actor) {
  if (a.state != "shelved") throw ConflictError(alarm_ref(a) + ": only a shelved alarm is unshelved");
  return change_alarm(a, "unshelve", actor, [](AlarmRecord& x) { x.shelved_until.reset(); });
}

AlarmEvent expire_shelve(AlarmRecord& a, const AlarmActor& actor) {
  AlarmActor server = actor;
  server.by = "server";
  if (server.comment.empty()) server.comment = "shelve expired at " + a.shelved_until.value_or("?");
  return change_alarm(a, "shelve_expired", server, [](AlarmRecord& x) { x.shelved_until.reset(); });
}

AlarmEvent reset_alarm(AlarmRecord& a, bool condition_clear, const AlarmActor& actor) {
  require_comment(actor, "reset");
  if (!a.latched) throw ConflictError(alarm_ref(a) + " and not latched: only a latched alarm is reset");
  return change_alarm(a, "reset", actor, [&](AlarmRecord& x) {
    x.latched = false;
    if (condition_clear) x.active = false;
  });
}

std::string iso_ms(std::int64_t ns) {
  const std::int64_t s = ns >= 0 ? ns / 1'000'000'000 : (ns - 999'999'999) / 1'000'000'000;
  const auto ms = static_cast<int>((ns - s * 1'000'000'000) / 1'000'000);
  const std::time_t t = static_cast<std::time_t>(s);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday,
                tm.tm_hour, tm.tm_min, tm.tm_sec, ms);
  return buf;
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace ambdiag::server::detail
