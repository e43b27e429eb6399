// Alarm-system KPIs after EEMUA 191 and ANSI/ISA-18.2 (section 16, alarm
// system performance), over a time range of the journal:
//
//   alarms_per_10min   raises per 10 minutes: average over the range and the
//                      peak 10-minute interval (ISA-18.2: about 1 acceptable,
//                      2 the most manageable; EEMUA 191: < 1 per 10 min)
//   flood              the share of 10-minute intervals with more than 10
//                      raises (ISA-18.2's flood; target < 1 % of the time)
//   chattering         alarms (pump, rule) raised 3 or more times within
//                      60 s (ISA-18.2 TR5's working definition; target: none)
//   stale              alarms active for more than 24 h at the range's end
//                      (ISA-18.2; target: fewer than 5 on any day)
//   top                the 10 alarms (pump, rule) raised most often, with
//                      their share of all raises
//
// A raise is a journal entry of kind "raise" (a new alarm or one that came
// back before it was acknowledged). Pure: the caller reads the journal.
#pragma once

#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/alarms.h"

namespace ambdiag::server::detail {

// `events`: the journal entries with from <= time < to; `active`: the
// alarms active now (for stale ones, those raised before to - 24 h).
nlohmann::json alarm_kpis(const std::vector<storage::AlarmEvent>& events, const std::vector<storage::AlarmRecord>& active,
                          std::int64_t from_ns, std::int64_t to_ns);

}  // namespace ambdiag::server::detail
