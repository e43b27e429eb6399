#include "analysis/model_frf.h"

#include <stdexcept>

#include "ambdiag/algorithms/model/frf_compare.h"
#include "ambdiag/core/error.h"
#include "ambdiag/core/frf_data.h"
#include "ambdiag/server/analysis_service.h"
#include "analysis/fit_model_file.h"
#include "analysis/run_analysis.h"
#include "analysis/views.h"

namespace ambdiag::server::detail {

namespace {

// The run and its current, finished analysis job, or NotFoundError.
std::pair<storage::RunInfo, storage::Job> analysed_run(storage::Historian& h, const std::string& run_id) {
  const auto run = h.find_run(run_id);
  if (!run) throw NotFoundError("no run '" + run_id + "'");
  auto job = current_analysis_job(h, *run);
  if (!job || job->status != storage::JobStatus::done)
    throw NotFoundError("run '" + run_id + "' has no finished analysis yet");
  return {*run, std::move(*job)};
}

// The analysis' measured FRF, the grid every curve of the run is drawn on.
FrfData measured_frf(storage::Historian& h, const storage::Job& job, const std::string& run_id) {
  const auto measured = h.find_artifact(job.job_id, "frf.csv");
  if (!measured) throw NotFoundError("the analysis of run '" + run_id + "' has no frf.csv");
  return parse_frf_csv(measured->data, "frf.csv of run " + run_id);
}

std::string labelled_csv(FrfData out, const storage::RunInfo& run, const storage::Job& job) {
  out.set_meta("pump_id", run.pump_id);
  out.set_meta("run_id", run.run_id);
  out.set_meta("model_version", std::to_string(job.key.model_version));
  return format_frf_csv(out);
}

}  // namespace

std::string model_frf_csv(storage::Historian& h, const std::string& run_id) {
  auto snap = h.snapshot();
  const auto [run, job] = analysed_run(h, run_id);
  const FrfData frf = measured_frf(h, job, run_id);
  const auto model = h.find_model(run.pump_id, job.key.model_version);
  if (!model) throw NotFoundError("the analysis of run '" + run_id + "' has no model");
  return labelled_csv(
      model_frf_like(plant_from_text(model->plant_json, "model version " + std::to_string(model->version)), frf), run, job);
}

std::string fit_frf_csv(storage::Historian& h, const std::string& run_id) {
  auto snap = h.snapshot();
  const auto [run, job] = analysed_run(h, run_id);
  const auto fit = h.find_artifact(job.job_id, "fit_model.json");
  if (!fit)
    throw NotFoundError("the analysis of run '" + run_id +
                        "' was made before fit_model.json was kept; the run's next analysis (after a new model or "
                        "reference version) keeps it");
  const FrfData grid = measured_frf(h, job, run_id);
  // The file is the server's own: a broken one is a server fault (500), not a bad request.
  try {
    return labelled_csv(fit_frf_like(nlohmann::json::parse(fit->data), grid), run, job);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("the stored fit_model.json of run '" + run_id + "' is not JSON: " + e.what());
  } catch (const InputError& e) {
    throw std::runtime_error("the stored fit_model.json of run '" + run_id + "': " + e.what());
  }
}

}  // namespace ambdiag::server::detail
