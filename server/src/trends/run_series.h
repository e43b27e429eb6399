// The trend values one analysed run contributes to its pump's series
// (rest.md, "Trends"): what both the historian's series and the alarm rules
// read, so a chart and an alarm always see the same number.
#pragma once

#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/trends.h"

namespace ambdiag::server::detail {

// {name, unit, value, sd?}: the historian keeps exactly these (trends.h).
using SeriesValue = storage::SeriesValue;

// The values of one analysis job's result (run_analysis.h's analyse_run keys):
//   run.speed_rpm                       the run's speed
//   fit.nrmse                           model vs measured
//   detection.ratio, detection.p_value  with a reference only
//   operating.LINK.factor               each fluid-seal link's fitted factor (with a reference)
//   mode.LABEL.f_hz, mode.LABEL.zeta    each labelled mode, with its sd
//   fault.NAME.PARAMETER                the best-ranked fault's parameters, when diagnosed
// Missing or non-finite entries are skipped, never invented. Sorted by name.
std::vector<SeriesValue> run_series(const nlohmann::json& analysis_result);

}  // namespace ambdiag::server::detail
