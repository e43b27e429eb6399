// The read side of the analysis (rest.md): what GET /pumps/{id},
// /runs/{id}/analysis and /jobs return, built from one historian
// connection (a REST reader), so any server on the database answers alike.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

// The analysis job that holds a run's current analysis: the one for the
// pump's newest model and reference versions. nullopt when the run is not
// analysed (not complete, not identification, no model) or not queued yet.
std::optional<storage::Job> current_analysis_job(storage::Historian& h, const storage::RunInfo& run);

// rest.md's pump: pump_id, model_version, reference {runs, status
// active|proposed, version}, health, active_alarms, last_run_id,
// last_analysis. nullopt for an unknown pump.
std::optional<nlohmann::json> pump_view(storage::Historian& h, const std::string& pump_id, int proposed_reference_runs);

// rest.md's analysis of a run; nullopt for an unknown run. `base_url` is
// where the run's files are served (".../runs/{id}").
std::optional<nlohmann::json> analysis_view(storage::Historian& h, const std::string& run_id, const std::string& base_url);

// "run 'R': its samples were dropped by retention at T" (`samples`), or
// "... its analyses' files (frf.csv, figures, fit model) ...": what a 410 says.
std::string dropped_by_retention(const storage::RunInfo& run, bool samples);

// rest.md's job (with "result" parsed, when done).
nlohmann::json job_json(const storage::Job& j, bool with_result);

}  // namespace ambdiag::server::detail
