// Historian: the job queue (tables jobs, job_artifacts; schema v4, leases v8).
//
// A job moves queued -> running -> done | failed, or to cancelled from
// queued or running; requeue_expired_jobs (and, for one server at its
// start, requeue_running_jobs) takes running back to queued. `attempts`
// counts the claims, and a worker names its claim by that number; a claim
// also sets a lease that the worker renews. finish_job, fail_job,
// set_job_progress and renew_job_lease only change a job that its attempt
// still holds (AMBDIAG_JOB_HELD: running, that attempt, lease not expired,
// at the time of the write, taken inside the transaction), so a worker
// whose job was requeued, cancelled, claimed again or whose lease ran out
// cannot store a second result. Each call is one write transaction (BEGIN
// IMMEDIATE), so connections of several processes on one file claim, finish
// and enqueue without a race: SQLite serialises the writers (busy timeout)
// and every check is re-done inside.
// On PostgreSQL writers run at once: a claim locks the row it takes and
// skips those others hold (FOR UPDATE OF j SKIP LOCKED), the enqueue relies
// on the key's unique constraint, and the fenced updates re-check their
// WHERE on the row they lock (docs/storage.md "Schema v8").
#include <algorithm>
#include <cmath>
#include <set>

#include <nlohmann/json.hpp>

#include "ambdiag/storage/historian.h"
#include "historian_impl.h"

namespace ambdiag::storage {

std::string to_string(JobStatus s) {
  switch (s) {
    case JobStatus::queued: return "queued";
    case JobStatus::running: return "running";
    case JobStatus::done: return "done";
    case JobStatus::failed: return "failed";
    case JobStatus::cancelled: return "cancelled";
  }
  return "queued";
}

std::optional<JobStatus> job_status_from(const std::string& s) {
  for (auto st : {JobStatus::queued, JobStatus::running, JobStatus::done, JobStatus::failed, JobStatus::cancelled})
    if (to_string(st) == s) return st;
  return std::nullopt;
}

namespace {

// The job columns in the order read_job_row reads them.
#define AMBDIAG_JOB_COLUMNS                                                                                   \
  "job_id, kind, pump_id, run_id, model_version, reference_version, status, progress, attempts, params, " \
  "depends_on, created_at, started_at, finished_at, error, result, worker, lease_expires_at"

Job read_job_row(const Stmt& s) {
  Job j;
  j.job_id = s.col_int(0);
  j.key.kind = s.col_text(1);
  j.key.pump_id = s.col_text(2);
  j.key.run_id = s.col_text(3);
  j.key.model_version = static_cast<int>(s.col_int(4));
  j.key.reference_version = static_cast<int>(s.col_int(5));
  j.status = job_status_from(s.col_text(6)).value_or(JobStatus::queued);  // CHECK keeps it one of the five
  j.progress = s.col_double(7);
  j.attempts = static_cast<int>(s.col_int(8));
  j.params_json = s.col_text(9);
  j.depends_on = s.col_opt_int(10);
  j.created_at = s.col_text(11);
  j.started_at = s.col_opt_text(12);
  j.finished_at = s.col_opt_text(13);
  j.error = s.col_opt_text(14);
  j.result_json = s.col_opt_text(15);
  j.worker = s.col_text(16);
  j.lease_expires_at = s.col_opt_text(17);
  return j;
}

std::string job_ref(std::int64_t job_id) { return "job " + std::to_string(job_id); }

// The condition under which attempt ?2 of job ?1 holds it at time ?3 (the
// fence of every write of an attempt, historian.h claim_job); the
// statements' own parameters are ?4 on. ?3 is taken inside the
// transaction, after the write lock: a wait for the lock must not stretch
// a lease.
#define AMBDIAG_JOB_HELD "job_id = ?1 AND status = 'running' AND attempts = ?2 AND lease_expires_at > ?3"

// Binds the fence; `now` must outlive the statement's steps (bound uncopied).
Stmt& bind_held(Stmt& s, std::int64_t job_id, int attempt, const std::string& now) {
  return s.bind(1, job_id).bind(2, std::int64_t{attempt}).bind(3, now);
}

std::string lease_end(std::chrono::milliseconds lease) {
  return utc_ms(std::chrono::system_clock::now() + std::max(lease, std::chrono::milliseconds(1)));
}

}  // namespace

std::pair<std::int64_t, bool> Historian::enqueue_job(const JobKey& key, const std::string& params_json,
                                                     std::optional<std::int64_t> depends_on) {
  impl_->require_writer("enqueue_job");
  if (key.kind.empty()) throw InputError("enqueue_job: empty kind");
  if (key.pump_id.empty()) throw InputError("enqueue_job " + quoted(key.kind) + ": empty pump_id");
  if (key.model_version < 0 || key.reference_version < 0)
    throw InputError("enqueue_job " + quoted(key.kind) + ": negative model or reference version");
  const std::string now = now_utc();
  Transaction tx(impl_->db, Transaction::Kind::write);
  if (auto held = find_job(key)) {
    tx.commit();
    return {held->job_id, false};
  }
  if (depends_on) {
    auto& d = impl_->stmt("SELECT 1 FROM jobs WHERE job_id = ?");
    d.bind(1, *depends_on);
    if (!d.step()) throw InputError("enqueue_job " + quoted(key.kind) + ": depends on unknown " + job_ref(*depends_on));
    d.reset();
  }
  // A writer of another process may enqueue the same key meanwhile
  // (PostgreSQL): then its job is the one, found below.
  auto& ins = impl_->stmt(
      "INSERT INTO jobs (kind, pump_id, run_id, model_version, reference_version, status, params, depends_on, "
      "created_at) VALUES (?, ?, ?, ?, ?, 'queued', ?, ?, ?) ON CONFLICT DO NOTHING RETURNING job_id");
  ins.bind(1, key.kind)
      .bind(2, key.pump_id)
      .bind(3, key.run_id)
      .bind(4, std::int64_t{key.model_version})
      .bind(5, std::int64_t{key.reference_version})
      .bind(6, params_json)
      .bind(8, now);
  if (depends_on)
    ins.bind(7, *depends_on);
  else
    ins.bind_null(7);
  if (!ins.step()) {
    auto held = find_job(key);
    if (!held) throw StorageError("enqueue_job: the insert returned no job_id");
    tx.commit();
    return {held->job_id, false};
  }
  const std::int64_t id = ins.col_int(0);
  ins.reset();
  tx.commit();
  return {id, true};
}

std::optional<Job> Historian::claim_job(const std::string& worker, const std::vector<std::string>& kinds,
                                        std::chrono::milliseconds lease) {
  impl_->require_writer("claim_job");
  const std::string kinds_json = nlohmann::json(kinds).dump();
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  // The oldest queued job whose dependency has ended. One whose dependency
  // failed or was cancelled fails in turn (its own dependents next time
  // round), and the search goes on.
  for (;;) {
    // PostgreSQL: the row is locked for this claim, and rows other claims
    // hold are skipped (their claimers will have taken them when they
    // commit); the kinds are a JSON array for both (json_each or
    // json_array_elements_text).
    auto& pick = impl_->dialect() == Dialect::postgres
                     ? impl_->stmt(
                           "SELECT j.job_id, j.depends_on, d.status, d.error FROM jobs j LEFT JOIN jobs d ON d.job_id = "
                           "j.depends_on WHERE j.status = 'queued' AND (j.kind IN (SELECT value FROM "
                           "json_array_elements_text(CAST(?1 AS json))) OR ?1 IS NULL) AND (j.depends_on IS NULL OR d.status IN "
                           "('done', 'failed', 'cancelled')) ORDER BY j.job_id LIMIT 1 FOR UPDATE OF j SKIP LOCKED")
                     : impl_->stmt(
                           "SELECT j.job_id, j.depends_on, d.status, d.error FROM jobs j LEFT JOIN jobs d ON d.job_id = "
                           "j.depends_on WHERE j.status = 'queued' AND (j.kind IN (SELECT value FROM "
                           "json_each(?1)) OR ?1 IS NULL) AND (j.depends_on IS NULL OR d.status IN ('done', 'failed', 'cancelled')) "
                           "ORDER BY j.job_id LIMIT 1");
    if (kinds.empty())
      pick.bind_null(1);
    else
      pick.bind(1, kinds_json);
    if (!pick.step()) {
      tx.commit();  // keeps the dependents failed on the way, if any
      return std::nullopt;
    }
    const std::int64_t id = pick.col_int(0);
    const auto dep = pick.col_opt_int(1);
    const std::string dep_status = pick.col_null(2) ? "" : pick.col_text(2);
    const auto dep_error = pick.col_opt_text(3);
    pick.reset();
    if (dep && dep_status != "done") {
      const std::string error = "depends on " + job_ref(*dep) +
                                (dep_status == "failed" ? ", which failed" : ", which was cancelled") +
                                (dep_error ? ": " + *dep_error : "");
      impl_->stmt("UPDATE jobs SET status = 'failed', error = ?, finished_at = ? WHERE job_id = ?")
          .bind(1, error)
          .bind(2, now)
          .bind(3, id)
          .run();
      continue;
    }
    impl_->stmt(
            "UPDATE jobs SET status = 'running', attempts = attempts + 1, started_at = ?, finished_at = NULL, "
            "worker = ?, progress = 0, error = NULL, result = NULL, lease_expires_at = ? WHERE job_id = ?")
        .bind(1, now)
        .bind(2, worker)
        .bind(3, lease_end(lease))
        .bind(4, id)
        .run();
    auto job = find_job(id);
    if (!job) throw StorageError("claim_job: " + job_ref(id) + " vanished inside the transaction");
    tx.commit();
    return job;
  }
}

bool Historian::set_job_progress(std::int64_t job_id, int attempt, double progress) {
  impl_->require_writer("set_job_progress");
  if (std::isnan(progress)) throw InputError("set_job_progress " + job_ref(job_id) + ": progress is NaN");
  progress = std::clamp(progress, 0.0, 1.0);
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  bind_held(impl_->stmt("UPDATE jobs SET progress = ?4 WHERE " AMBDIAG_JOB_HELD), job_id, attempt, now)
      .bind(4, progress)
      .run();
  if (impl_->db.changes() != 1) return false;
  tx.commit();
  return true;
}

bool Historian::renew_job_lease(std::int64_t job_id, int attempt, std::chrono::milliseconds lease) {
  impl_->require_writer("renew_job_lease");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc(), until = lease_end(lease);
  bind_held(impl_->stmt("UPDATE jobs SET lease_expires_at = ?4 WHERE " AMBDIAG_JOB_HELD), job_id, attempt, now)
      .bind(4, until)
      .run();
  if (impl_->db.changes() != 1) return false;
  tx.commit();
  return true;
}

bool Historian::finish_job(std::int64_t job_id, int attempt, const std::string& result_json,
                           const std::vector<JobArtifact>& artifacts,
                           const std::optional<std::vector<SeriesValue>>& series) {
  impl_->require_writer("finish_job");
  if (series) check_series_values(*series, "finish_job " + job_ref(job_id));
  std::set<std::string> names;
  for (const auto& a : artifacts) {
    if (a.name.empty()) throw InputError("finish_job " + job_ref(job_id) + ": a file without a name");
    if (!names.insert(a.name).second)
      throw InputError("finish_job " + job_ref(job_id) + ": file " + quoted(a.name) + " given twice");
  }
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  // The fence: only the attempt that holds the job stores its result.
  bind_held(impl_->stmt("UPDATE jobs SET status = 'done', result = ?4, error = NULL, progress = 1, finished_at = ?3, "
                        "lease_expires_at = NULL WHERE " AMBDIAG_JOB_HELD),
            job_id, attempt, now)
      .bind(4, result_json)
      .run();
  if (impl_->db.changes() != 1) return false;
  // A done job is never claimed again, so there is nothing of another
  // attempt to remove; cleared all the same so the files are exactly this
  // result's.
  impl_->stmt("DELETE FROM job_artifacts WHERE job_id = ?").bind(1, job_id).run();
  auto& ins = impl_->stmt("INSERT INTO job_artifacts (job_id, name, content_type, data) VALUES (?, ?, ?, ?)");
  for (const auto& a : artifacts) {
    ins.reset()
        .bind(1, job_id)
        .bind(2, a.name)
        .bind(3, a.content_type)
        .bind_blob(4, {reinterpret_cast<const std::uint8_t*>(a.data.data()), a.data.size()})
        .run();
  }
  if (series) {
    // Only an analysis of a run feeds its pump's series (trends.h).
    auto& k = impl_->stmt("SELECT kind, pump_id, run_id FROM jobs WHERE job_id = ?");
    k.bind(1, job_id).step();
    const std::string kind = k.col_text(0), pump_id = k.col_text(1), run_id = k.col_text(2);
    k.reset();
    if (kind == "analysis" && !run_id.empty()) put_run_series(*impl_, job_id, pump_id, run_id, *series);
  }
  tx.commit();
  return true;
}

bool Historian::fail_job(std::int64_t job_id, int attempt, const std::string& error) {
  impl_->require_writer("fail_job");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  bind_held(impl_->stmt("UPDATE jobs SET status = 'failed', error = ?4, finished_at = ?3, lease_expires_at = NULL "
                        "WHERE " AMBDIAG_JOB_HELD),
            job_id, attempt, now)
      .bind(4, error.empty() ? std::string("failed without a message") : error)
      .run();
  if (impl_->db.changes() != 1) return false;
  tx.commit();
  return true;
}

bool Historian::release_job(std::int64_t job_id, int attempt) {
  impl_->require_writer("release_job");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string now = now_utc();
  bind_held(impl_->stmt("UPDATE jobs SET status = 'queued', progress = 0, worker = '', lease_expires_at = NULL "
                        "WHERE " AMBDIAG_JOB_HELD),
            job_id, attempt, now)
      .run();
  if (impl_->db.changes() != 1) return false;
  tx.commit();
  return true;
}

namespace {

// The running jobs (with `expired_only`, those whose lease has expired),
// queued again or failed after max_attempts claims with "gave up after N
// attempts: <why>".
Historian::Requeued requeue_running(Historian::Impl& impl, bool expired_only, int max_attempts, const std::string& why) {
  Historian::Requeued r;
  Transaction tx(impl.db, Transaction::Kind::write);
  const std::string now = now_utc();
  const std::int64_t only_expired = expired_only ? 1 : 0;
  // A job that was running at every one of max_attempts deaths of its
  // worker is likely what kills it: it fails instead of being claimed again.
#define AMBDIAG_JOB_LOST "status = 'running' AND (?1 = 0 OR lease_expires_at IS NULL OR lease_expires_at <= ?2)"
  impl.stmt("UPDATE jobs SET status = 'failed', finished_at = ?2, worker = '', lease_expires_at = NULL, "
            "error = 'gave up after ' || attempts || ' attempts: ' || ?4 "
            "WHERE " AMBDIAG_JOB_LOST " AND attempts >= ?3")
      .bind(1, only_expired)
      .bind(2, now)
      .bind(3, static_cast<std::int64_t>(std::max(1, max_attempts)))
      .bind(4, why)
      .run();
  r.failed = impl.db.changes();
  // attempts stays: the next claim is a new attempt, and the old one's
  // worker (if it still lives) is refused.
  impl.stmt("UPDATE jobs SET status = 'queued', progress = 0, worker = '', lease_expires_at = NULL WHERE " AMBDIAG_JOB_LOST)
      .bind(1, only_expired)
      .bind(2, now)
      .run();
#undef AMBDIAG_JOB_LOST
  r.requeued = impl.db.changes();
  tx.commit();
  return r;
}

}  // namespace

int Historian::requeue_running_jobs(int max_attempts) {
  impl_->require_writer("requeue_running_jobs");
  return requeue_running(*impl_, false, max_attempts, "the server stopped during each").requeued;
}

Historian::Requeued Historian::requeue_expired_jobs(int max_attempts) {
  impl_->require_writer("requeue_expired_jobs");
  return requeue_running(*impl_, true, max_attempts, "each lost its lease (its worker died or stalled)");
}

int Historian::cancel_superseded_jobs(const std::string& pump_id, const std::string& kind, int model_version,
                                      int reference_version) {
  impl_->require_writer("cancel_superseded_jobs");
  Transaction tx(impl_->db, Transaction::Kind::write);
  const std::string error = "superseded by model version " + std::to_string(model_version) + ", reference version " +
                            std::to_string(reference_version);
  impl_->stmt(
          "UPDATE jobs SET status = 'cancelled', finished_at = ?1, error = ?6 "
          "WHERE pump_id = ?2 AND kind = ?3 AND status = 'queued' AND (model_version < ?4 OR reference_version < ?5)")
      .bind(1, now_utc())
      .bind(2, pump_id)
      .bind(3, kind)
      .bind(4, std::int64_t{model_version})
      .bind(5, std::int64_t{reference_version})
      .bind(6, error)
      .run();
  const int n = impl_->db.changes();
  tx.commit();
  return n;
}

bool Historian::cancel_job(std::int64_t job_id, const std::string& reason) {
  impl_->require_writer("cancel_job");
  Transaction tx(impl_->db, Transaction::Kind::write);
  impl_->stmt(
          "UPDATE jobs SET status = 'cancelled', error = ?, finished_at = ?, lease_expires_at = NULL "
          "WHERE job_id = ? AND status IN ('queued', 'running')")
      .bind(1, reason.empty() ? std::string("cancelled") : reason)
      .bind(2, now_utc())
      .bind(3, job_id)
      .run();
  if (impl_->db.changes() != 1) return false;
  tx.commit();
  return true;
}

std::optional<Job> Historian::find_job(std::int64_t job_id) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_JOB_COLUMNS " FROM jobs WHERE job_id = ?");
  s.bind(1, job_id);
  if (!s.step()) return std::nullopt;
  auto j = read_job_row(s);
  s.reset();
  return j;
}

std::optional<Job> Historian::find_job(const JobKey& key) {
  auto& s = impl_->stmt("SELECT " AMBDIAG_JOB_COLUMNS
                        " FROM jobs WHERE kind = ? AND pump_id = ? AND run_id = ? AND model_version = ? "
                        "AND reference_version = ?");
  s.bind(1, key.kind)
      .bind(2, key.pump_id)
      .bind(3, key.run_id)
      .bind(4, std::int64_t{key.model_version})
      .bind(5, std::int64_t{key.reference_version});
  if (!s.step()) return std::nullopt;
  auto j = read_job_row(s);
  s.reset();
  return j;
}

std::vector<Job> Historian::list_jobs(const JobFilter& filter) {
  if (filter.limit < 1) throw InputError("list_jobs: limit must be >= 1");
  // One statement per leading key, so that the planner walks that key's
  // index (newest first) and the other conditions only filter.
#define AMBDIAG_JOB_FILTERS \
  "(run_id = ?1 OR ?1 IS NULL) AND (pump_id = ?2 OR ?2 IS NULL) AND (kind = ?3 OR ?3 IS NULL) AND (status = ?4 OR ?4 IS NULL)"
  auto& s = filter.run_id ? impl_->stmt("SELECT " AMBDIAG_JOB_COLUMNS " FROM jobs WHERE run_id = ?1 AND " AMBDIAG_JOB_FILTERS
                                        " ORDER BY job_id DESC LIMIT ?5")
            : filter.pump_id ? impl_->stmt("SELECT " AMBDIAG_JOB_COLUMNS " FROM jobs WHERE pump_id = ?2 AND " AMBDIAG_JOB_FILTERS
                                           " ORDER BY job_id DESC LIMIT ?5")
                             : impl_->stmt("SELECT " AMBDIAG_JOB_COLUMNS " FROM jobs WHERE " AMBDIAG_JOB_FILTERS
                                           " ORDER BY job_id DESC LIMIT ?5");
#undef AMBDIAG_JOB_FILTERS
  const auto bind_opt = [&](int i, const std::optional<std::string>& v) {
    if (v)
      s.bind(i, *v);
    else
      s.bind_null(i);
  };
  bind_opt(1, filter.run_id);
  bind_opt(2, filter.pump_id);
  bind_opt(3, filter.kind);
  const auto status = filter.status ? std::optional<std::string>(to_string(*filter.status)) : std::nullopt;
  bind_opt(4, status);  // bound without a copy: must outlive the steps
  s.bind(5, std::int64_t{filter.limit});
  std::vector<Job> out;
  while (s.step()) out.push_back(read_job_row(s));
  return out;
}

std::int64_t Historian::count_jobs(JobStatus status) {
  auto& s = impl_->stmt("SELECT count(*) FROM jobs WHERE status = ?");
  const std::string st = to_string(status);
  s.bind(1, st).step();
  const auto n = s.col_int(0);
  s.reset();
  return n;
}

std::map<std::pair<std::string, std::string>, std::int64_t> Historian::count_jobs_by_kind_and_status() {
  auto& s = impl_->stmt("SELECT kind, status, count(*) FROM jobs GROUP BY kind, status");
  std::map<std::pair<std::string, std::string>, std::int64_t> out;
  while (s.step()) out[{s.col_text(0), s.col_text(1)}] = s.col_int(2);
  s.reset();
  return out;
}

std::optional<JobArtifact> Historian::find_artifact(std::int64_t job_id, const std::string& name) {
  auto& s = impl_->stmt("SELECT content_type, data FROM job_artifacts WHERE job_id = ? AND name = ?");
  s.bind(1, job_id).bind(2, name);
  if (!s.step()) return std::nullopt;
  const auto blob = s.col_blob(1);
  JobArtifact a{name, s.col_text(0), std::string(reinterpret_cast<const char*>(blob.data()), blob.size())};
  s.reset();
  return a;
}

std::vector<std::string> Historian::list_artifacts(std::int64_t job_id) {
  auto& s = impl_->stmt("SELECT name FROM job_artifacts WHERE job_id = ? ORDER BY name");
  s.bind(1, job_id);
  std::vector<std::string> out;
  while (s.step()) out.push_back(s.col_text(0));
  return out;
}

}  // namespace ambdiag::storage
