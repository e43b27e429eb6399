#include "views.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;
using storage::JobStatus;

json parse_or_null(const std::optional<std::string>& text) {
  if (!text) return nullptr;
  try {
    return json::parse(*text);
  } catch (const json::exception&) {
    return nullptr;
  }
}

}  // namespace

namespace {

// The analysis job of the run for the pump's versions (m, r).
std::optional<storage::Job> analysis_job(storage::Historian& h, const storage::RunInfo& run, int m, int r) {
  return h.find_job(storage::JobKey{"analysis", run.pump_id, run.run_id, m, r});
}

// The first `n` complete identification runs of `runs` (oldest first).
std::vector<std::string> proposed_reference(const std::vector<storage::RunInfo>& runs, int n) {
  std::vector<std::string> ids;
  for (const auto& r : runs) {
    if (static_cast<int>(ids.size()) >= n) break;
    if (r.status == storage::RunStatus::complete && r.kind == "identification") ids.push_back(r.run_id);
  }
  return ids;
}

}  // namespace

std::optional<storage::Job> current_analysis_job(storage::Historian& h, const storage::RunInfo& run) {
  const auto model = h.find_model(run.pump_id);
  if (!model) return std::nullopt;
  const auto ref = h.find_reference(run.pump_id);
  return analysis_job(h, run, model->version, ref ? ref->version : 0);
}

std::optional<json> pump_view(storage::Historian& h, const std::string& pump_id, int proposed_reference_runs) {
  auto snap = h.snapshot();
  const auto summary = h.find_pump(pump_id);
  const auto model = h.find_model(pump_id);
  if (!summary && !model) return std::nullopt;
  const auto ref = h.find_reference(pump_id);
  const auto runs = h.list_runs(pump_id);  // by started_at
  json j = {{"pump_id", pump_id}, {"active_alarms", 0}, {"n_runs", summary ? summary->n_runs : 0}};
  if (model) j["model_version"] = model->version;
  if (ref) {
    j["reference"] = {{"runs", ref->run_ids}, {"status", "active"}, {"version", ref->version}, {"created_at", ref->created_at},
                      {"created_by", ref->created_by}};
  } else if (auto ids = proposed_reference(runs, proposed_reference_runs);
             static_cast<int>(ids.size()) >= proposed_reference_runs && proposed_reference_runs > 0) {
    j["reference"] = {{"runs", ids}, {"status", "proposed"}};
  }
  // Health: the worst active alarm (high or critical: alarm; low or
  // medium: warning); without one, the newest analysed run's detection
  // (a change detected that has not raised an alarm yet is a warning);
  // unknown without a model, a reference or a finished analysis.
  int active_alarms = 0;
  bool severe = false;
  for (const auto& a : h.open_alarms(pump_id)) {
    if (!a.active) continue;
    ++active_alarms;
    severe = severe || a.severity == "high" || a.severity == "critical";
  }
  const std::string worst = severe ? "alarm" : active_alarms > 0 ? "warning" : "";
  j["active_alarms"] = active_alarms;
  std::string health = "unknown";
  if (summary && !summary->last_run_id.empty()) j["last_run_id"] = summary->last_run_id;
  for (auto it = runs.rbegin(); model && it != runs.rend(); ++it) {
    const auto job = analysis_job(h, *it, model->version, ref ? ref->version : 0);
    if (!job || job->status != JobStatus::done) continue;
    const json result = parse_or_null(job->result_json);
    json last = {{"run_id", it->run_id}, {"job_id", job->job_id}, {"finished_at", job->finished_at.value_or("")}};
    if (result.is_object() && result.contains("detection") && result["detection"].is_object()) {
      const bool detected = result["detection"].value("detected", false);
      last["detected"] = detected;
      last["ratio"] = result["detection"].value("ratio", 0.0);
      if (detected && result["diagnosis"].is_object() && !result["diagnosis"]["faults"].empty())
        last["fault"] = result["diagnosis"]["faults"][0].value("fault", "");
      health = detected ? "warning" : "ok";
    }
    j["last_analysis"] = last;
    break;
  }
  j["health"] = worst.empty() ? health : worst;
  return j;
}

json job_json(const storage::Job& job, bool with_result) {
  json j = {{"job_id", job.job_id},
            {"kind", job.key.kind},
            {"pump_id", job.key.pump_id},
            {"status", storage::to_string(job.status)},
            {"progress", job.progress},
            {"attempts", job.attempts},
            {"created_at", job.created_at}};
  if (!job.key.run_id.empty()) j["run_id"] = job.key.run_id;
  if (job.key.model_version > 0) j["model_version"] = job.key.model_version;
  if (job.key.reference_version > 0) j["reference_version"] = job.key.reference_version;
  if (job.started_at) j["started_at"] = *job.started_at;
  if (job.finished_at) j["finished_at"] = *job.finished_at;
  if (job.error) j["error"] = *job.error;
  if (job.depends_on) j["depends_on"] = *job.depends_on;
  // Who runs it and until when its attempt holds it (docs/service.md "Several servers").
  if (job.status == JobStatus::running) j["worker"] = job.worker;
  if (job.lease_expires_at) j["lease_expires_at"] = *job.lease_expires_at;
  if (with_result && job.result_json) j["result"] = parse_or_null(job.result_json);
  return j;
}

std::optional<json> analysis_view(storage::Historian& h, const std::string& run_id, const std::string& base_url) {
  auto snap = h.snapshot();
  const auto run = h.find_run(run_id);
  if (!run) return std::nullopt;
  json j = {{"run_id", run_id}, {"pump_id", run->pump_id}};
  const auto model = h.find_model(run->pump_id);
  if (!model) {
    j["status"] = "waiting";
    j["reason"] = "pump '" + run->pump_id + "' has no model";
    return j;
  }
  j["model_version"] = model->version;
  if (run->kind != "identification") {
    j["status"] = "done";
    j["reason"] = "a " + run->kind + " run: only identification runs are analysed";
    j["detection"] = nullptr;
    return j;
  }
  if (run->status == storage::RunStatus::receiving) {
    j["status"] = "waiting";
    j["reason"] = "run still receiving";
    return j;
  }
  if (run->status == storage::RunStatus::incomplete) {
    j["status"] = "failed";
    j["error"] = "run incomplete: " + run->status_reason;
    return j;
  }
  const auto ref = h.find_reference(run->pump_id);
  const auto job = analysis_job(h, *run, model->version, ref ? ref->version : 0);
  if (!job) {
    j["status"] = "queued";
    j["progress"] = 0.0;
    return j;
  }
  j["job_id"] = job->job_id;
  j["status"] = job->status == JobStatus::cancelled ? "failed" : storage::to_string(job->status);
  j["progress"] = job->progress;
  j["attempts"] = job->attempts;
  if (job->key.reference_version > 0) j["reference_version"] = job->key.reference_version;
  if (job->error) j["error"] = *job->error;
  if (job->status == JobStatus::done) {
    const json result = parse_or_null(job->result_json);
    if (result.is_object()) j.update(result);
    json files = json::object();
    for (const auto& name : h.list_artifacts(job->job_id)) files[name] = base_url + "/" + name;
    j["files"] = files;
  }
  if (!j.contains("detection")) j["detection"] = nullptr;
  return j;
}

std::string dropped_by_retention(const storage::RunInfo& run, bool samples) {
  const auto& at = samples ? run.samples_dropped_at : run.frf_dropped_at;
  return "run '" + run.run_id + "': its " + (samples ? "samples were" : "analyses' files (frf.csv, figures, fit model) were") +
         " dropped by retention at " + at.value_or("?") + " (the retention policy of pump '" +
         run.pump_id + "'); its header, analysis results and trend points are kept";
}

}  // namespace ambdiag::server::detail
