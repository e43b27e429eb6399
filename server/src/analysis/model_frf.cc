#include "analysis/model_frf.h"

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/server/analysis_service.h"
#include "analysis/run_analysis.h"
#include "analysis/views.h"

namespace ambdiag::server::detail {

std::string model_frf_csv(storage::Historian& h, const std::string& run_id) {
  auto snap = h.snapshot();
  const auto run = h.find_run(run_id);
  if (!run) throw NotFoundError("no run '" + run_id + "'");
  const auto job = current_analysis_job(h, *run);
  if (!job || job->status != storage::JobStatus::done)
    throw NotFoundError("run '" + run_id + "' has no finished analysis yet");
  const auto measured = h.find_artifact(job->job_id, "frf.csv");
  if (!measured && run->frf_dropped_at) throw GoneError(dropped_by_retention(*run, false));
  const auto model = h.find_model(run->pump_id, job->key.model_version);
  if (!measured || !model)
    throw NotFoundError("the analysis of run '" + run_id + "' has no frf.csv or no model");
  const FrfData frf = parse_frf_csv(measured->data, "frf.csv of run " + run_id);
  FrfData out = model_frf_like(
      plant_from_text(model->plant_json, "model version " + std::to_string(model->version)), frf);
  out.set_meta("pump_id", run->pump_id);
  out.set_meta("run_id", run_id);
  out.set_meta("model_version", std::to_string(model->version));
  return format_frf_csv(out);
}

}  // namespace ambdiag::server::detail
