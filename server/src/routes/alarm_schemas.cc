// The alarms' answers (rest.md "Alarms"; alarm_evaluator.h's alarm_json,
// alarm_event_json; alarm_kpis.h; a pump's rules: docs/service.md "Alarms").
#include "routes/api_schemas.h"

namespace ambdiag::server::detail {

using namespace schema;

void add_alarm_schemas(RouteTable& t) {
  const json severity = one_of({"low", "medium", "high", "critical"});
  t.add_schema("Alarm", object({{"alarm_id", integer()},
                                {"pump_id", string()},
                                {"rule", string()},
                                {"severity", severity},
                                {"state", alarm_state()},
                                {"active", boolean()},
                                {"acknowledged", boolean()},
                                {"raised_at", time()},
                                {"run_id", string()},
                                {"message", string()}},
                               {{"cleared_at", time()},
                                {"fault", string()},
                                {"latched", boolean()},
                                {"updated_at", time()},
                                {"value", number()},
                                {"shelved_until", time()},
                                {"suppressed_reason", string()},
                                {"out_of_service", boolean()}}));
  const Props transition = {{"seq", integer()}, {"time", time()}, {"from", alarm_state()}, {"to", alarm_state()}, {"by", string()}};
  const Props transition_optional = {
      {"comment", string()},
      {"run_id", string()},
      {"kind", one_of({"raise", "clear", "ack", "shelve", "unshelve", "shelve_expired", "suppress", "release", "reset",
                       "update", "out_of_service", "in_service"})}};
  t.add_schema("AlarmTransition", object(transition, transition_optional));
  Props journal = transition;
  journal.insert(journal.end(), {{"alarm_id", integer()}, {"pump_id", string()}});
  Props journal_optional = transition_optional;
  journal_optional.emplace_back("rule", string());
  t.add_schema("AlarmJournalEvent", object(journal, journal_optional));
  // Chattering and stale alarms: what counts as one, and the list.
  const auto listed = [](const Props& keys) { return object({{"definition", string()}, {"alarms", array(object(keys))}}); };
  t.add_schema("AlarmKpis",
               object({{"from", time()},
                       {"to", time()},
                       {"raises", integer()},
                       {"intervals_10min", integer()},
                       {"alarms_per_10min", object({{"average", number()}, {"peak", integer()}})},
                       {"flood", object({{"threshold_per_10min", integer()}, {"intervals", integer()}, {"share_of_time", number()}})},
                       {"chattering", listed({{"pump_id", string()}, {"rule", string()}, {"raises", integer()}, {"most_in_60s", integer()}})},
                       {"stale", listed({{"alarm_id", integer()}, {"pump_id", string()}, {"rule", string()}, {"raised_at", time()},
                                         {"active_h", number()}})},
                       {"top", array(object({{"pump_id", string()}, {"rule", string()}, {"raises", integer()}, {"share", number()}}))}}));
  // One rule as GET shows it (a PUT may give only the keys it changes);
  // the optional keys belong to some kinds of rule only.
  t.add_schema("AlarmRule", object({{"id", string()},
                                    {"enabled", boolean()},
                                    {"levels", array(object({{"severity", severity}, {"raise", number()}}))},
                                    {"clear", number()},
                                    {"on_delay", object({{"k", integer()}, {"n", integer()}})},
                                    {"off_delay", integer()},
                                    {"latch", nullable(severity)}},
                                   {{"parameter", string()},
                                    {"direction", one_of({"below", "above"})},
                                    {"nominal", number()},
                                    {"min_relative_shift", number()},
                                    {"k_sd", number()},
                                    {"clearance_m", nullable(number())},
                                    {"limit_s", number()},
                                    {"nrmse_limit", number()}}));
  t.add_schema("AlarmRules", object({{"pump_id", string()},
                                     {"plant_state", object({{"speed_band", number()}, {"stopped_below_rpm", number()}})},
                                     {"rules", array(ref("AlarmRule"))},
                                     {"version", integer()},
                                     {"source", one_of({"pump", "defaults"})}},
                                    {{"created_at", time()}, {"created_by", string()}}));
}

}  // namespace ambdiag::server::detail
