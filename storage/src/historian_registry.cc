// Historian: the pumps' plant models and references (tables models,
// pump_references, reference_runs; schema v4). Versions count 1, 2, ... per
// pump and are never overwritten: a job names the versions it ran against.
#include <set>

#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

namespace {

void require_pump_id(const std::string& pump_id, const char* what) {
  if (pump_id.empty()) throw InputError(std::string(what) + ": empty pump_id");
}

}  // namespace

int Historian::put_model(const std::string& pump_id, const std::string& plant_json, const std::string& created_by,
                         const std::string& comment) {
  impl_->require_writer("put_model");
  require_pump_id(pump_id, "put_model");
  if (plant_json.empty()) throw InputError("put_model " + quoted(pump_id) + ": empty plant model");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  impl_->register_pump(pump_id, now);
  const auto version = impl_->next_version("SELECT coalesce(max(version), 0) + 1 FROM models WHERE pump_id = ?", pump_id);
  impl_->stmt(
          "INSERT INTO models (pump_id, version, plant_json, created_at, created_by, comment) "
          "VALUES (?, ?, ?, ?, ?, ?)")
      .bind(1, pump_id)
      .bind(2, version)
      .bind(3, plant_json)
      .bind(4, now)
      .bind(5, created_by)
      .bind(6, comment)
      .run();
  tx.commit();
  return static_cast<int>(version);
}

std::optional<ModelVersion> Historian::find_model(const std::string& pump_id, std::optional<int> version) {
  auto& s = version ? impl_->stmt(
                          "SELECT version, plant_json, created_at, created_by, comment FROM models "
                          "WHERE pump_id = ? AND version = ?")
                    : impl_->stmt(
                          "SELECT version, plant_json, created_at, created_by, comment FROM models "
                          "WHERE pump_id = ? ORDER BY version DESC LIMIT 1");
  s.bind(1, pump_id);
  if (version) s.bind(2, std::int64_t{*version});
  if (!s.step()) return std::nullopt;
  ModelVersion m{pump_id, static_cast<int>(s.col_int(0)), s.col_text(1), s.col_text(2), s.col_text(3), s.col_text(4)};
  s.reset();
  return m;
}

std::vector<ModelVersion> Historian::list_models(const std::string& pump_id) {
  auto& s = impl_->stmt(
      "SELECT version, created_at, created_by, comment FROM models WHERE pump_id = ? ORDER BY version");
  s.bind(1, pump_id);
  std::vector<ModelVersion> out;
  while (s.step()) out.push_back({pump_id, static_cast<int>(s.col_int(0)), "", s.col_text(1), s.col_text(2), s.col_text(3)});
  return out;
}

int Historian::put_reference(const std::string& pump_id, const std::vector<std::string>& run_ids,
                             const std::string& created_by) {
  impl_->require_writer("put_reference");
  require_pump_id(pump_id, "put_reference");
  const std::string ctx = "put_reference " + quoted(pump_id);
  if (run_ids.empty()) throw InputError(ctx + ": no runs (a reference needs at least one)");
  // Checked inside the write transaction: a run cannot change between the
  // check and the insert.
  Transaction tx(impl_->db, Transaction::Kind::write);
  std::set<std::string> seen;
  for (const auto& run_id : run_ids) {
    const std::string where = ctx + ": run " + quoted(run_id);
    if (!seen.insert(run_id).second) throw InputError(where + " is listed twice");
    // A run whose samples retention dropped is learnt from the frf.csv an
    // analysis of it kept (the reference job reads that first).
    auto& s = impl_->stmt(
        "SELECT pump_id, kind, status, status_reason, samples_dropped_at, EXISTS (SELECT 1 FROM jobs j JOIN "
        "job_artifacts a ON a.job_id = j.job_id WHERE j.run_id = runs.run_id AND j.kind = 'analysis' AND "
        "j.status = 'done' AND a.name = 'frf.csv') FROM runs WHERE run_id = ?");
    s.bind(1, run_id);
    if (!s.step()) throw InputError(where + ": unknown run");
    const std::string run_pump = s.col_text(0), kind = s.col_text(1), status = s.col_text(2), reason = s.col_text(3);
    const auto dropped_at = s.col_opt_text(4);
    const bool frf_kept = s.col_int(5) != 0;
    s.reset();
    if (run_pump != pump_id) throw InputError(where + " is of pump " + quoted(run_pump));
    if (status != "complete")
      throw InputError(where + " is " + status + (reason.empty() ? "" : " (" + reason + ")") + ", not complete");
    if (kind != "identification") throw InputError(where + " is a " + kind + " run, not an identification run");
    if (dropped_at && !frf_kept)
      throw InputError(where + ": its samples were dropped by retention at " + *dropped_at +
                       " and no analysis of it kept its FRF");
  }
  const auto version = impl_->next_version("SELECT coalesce(max(version), 0) + 1 FROM pump_references WHERE pump_id = ?", pump_id);
  impl_->stmt("INSERT INTO pump_references (pump_id, version, created_at, created_by) VALUES (?, ?, ?, ?)")
      .bind(1, pump_id)
      .bind(2, version)
      .bind(3, now_utc())
      .bind(4, created_by)
      .run();
  auto& ins = impl_->stmt("INSERT INTO reference_runs (pump_id, version, idx, run_id) VALUES (?, ?, ?, ?)");
  for (std::size_t i = 0; i < run_ids.size(); ++i)
    ins.reset().bind(1, pump_id).bind(2, version).bind(3, static_cast<std::int64_t>(i)).bind(4, run_ids[i]).run();
  tx.commit();
  return static_cast<int>(version);
}

std::optional<ReferenceVersion> Historian::find_reference(const std::string& pump_id, std::optional<int> version) {
  // The version row and its runs from one committed state.
  Transaction tx(impl_->db, Transaction::Kind::read);
  auto& s = version ? impl_->stmt(
                          "SELECT version, created_at, created_by FROM pump_references WHERE pump_id = ? AND version = ?")
                    : impl_->stmt(
                          "SELECT version, created_at, created_by FROM pump_references WHERE pump_id = ? "
                          "ORDER BY version DESC LIMIT 1");
  s.bind(1, pump_id);
  if (version) s.bind(2, std::int64_t{*version});
  if (!s.step()) return std::nullopt;
  ReferenceVersion r{pump_id, static_cast<int>(s.col_int(0)), {}, s.col_text(1), s.col_text(2)};
  s.reset();
  auto& runs = impl_->stmt("SELECT run_id FROM reference_runs WHERE pump_id = ? AND version = ? ORDER BY idx");
  runs.bind(1, pump_id).bind(2, std::int64_t{r.version});
  while (runs.step()) r.run_ids.push_back(runs.col_text(0));
  tx.commit();
  return r;
}

}  // namespace ambdiag::storage
