// What a chart draws of an alarm rule on the series it watches (rest.md
// "Trends": "the alarm limits added to the series they apply to"): the
// rule's raise levels and its clear limit, turned back from the rule's value
// (a ratio, a normalised shift) into the series' own unit.
#pragma once

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "alarms/alarm_rules.h"

namespace ambdiag::server::detail {

// {"rule", "lines": [{"kind": "raise", "severity", "value"} | {"kind": "clear", "value"}]}
// in the series' unit, for the enabled rule that watches `series`:
//   detection.ratio           rule `detection` (the value is the ratio)
//   fault.NAME.PARAMETER      rule `fault.NAME` when it compares PARAMETER (with
//                             a nominal: lines on both sides of it)
//   mode.LABEL.f_hz / .zeta   rules `mode.*`: the reference mean shifted by the
//                             level times max(min shift, k_sd sd), both ways
//                             (needs `reference`: {"mean", "sd"?}, else nothing)
//   fit.nrmse                 rule `poor_data` (the level times nrmse_limit)
// nullopt for other series (monitoring, speed, seal factors) or a disabled rule.
std::optional<nlohmann::json> alarm_limits(const AlarmRuleSet& rules, const std::string& series,
                                           const std::optional<nlohmann::json>& reference);

}  // namespace ambdiag::server::detail
