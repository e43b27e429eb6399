// The server's analysis side (rest.md "Pumps, models, references" and
// "Analysis, without being asked"; docs/service.md): it keeps each pump's
// models and references, queues one analysis job per complete
// identification run of a pump with a model, and runs the jobs on worker
// threads that only take the CPU ingest leaves (SCHED_IDLE).
//
// Jobs live in the historian (storage/service.h) with a lease that the
// process running them renews, so a job whose worker died or stalled is
// queued again by any analysis process once its lease expires, and a result
// is stored once: a worker's result is refused when its attempt no longer
// holds the job. Changing a pump's model or reference queues the runs again
// against the new versions and cancels what the old ones still had queued.
// What it does is announced in the historian's events table, in the same
// transaction (GET /api/v1/events on every server).
//
// Several processes may run one on the same database (docs/service.md
// "Several servers"): with workers, a process runs jobs; without (workers
// 0), it only takes REST writes and queues jobs.
//
// Threads: every public call may come from any thread (REST workers, the
// ingest's commit thread); each thread here has its own connection.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::storage {
class Historian;
}

namespace ambdiag::server {

class MetricsRegistry;

struct AnalysisOptions {
  std::string db_path;
  // Analysis threads. 0: this process runs no jobs (no workers, no lease
  // requeue, no alarm timer, no start-up catch-up); REST writes and
  // queueing still work.
  int workers = 2;
  // Names this process' workers ("INSTANCE/worker-K", a job's `worker`);
  // empty: "worker-K".
  std::string instance;
  // How long a claim holds a job without a renewal; renewed every third of
  // it, expired leases requeued every half (`ambdiag serve --job-lease`).
  std::chrono::milliseconds job_lease{10000};
  int proposed_reference_runs = 3;  // first N complete identification runs proposed as the reference
  double alpha = 1e-5;          // false-alarm rate of detection per run: kRecommendedAlphaPerRun (docs/diagnosis.md)
  bool idle_priority = true;    // workers at SCHED_IDLE: ingest and REST first
  bool verbose = true;          // one line per job on stderr
  // Job durations and CPU by kind are registered here (GET /metrics).
  MetricsRegistry* metrics = nullptr;
  // Alarms (docs/service.md "Alarms"): the server's default rules, applied
  // over the built-in ones rule by rule (`ambdiag serve --alarm-defaults
  // FILE`); null: the built-in ones. Validated by the constructor
  // (InputError naming the field).
  nlohmann::json alarm_defaults = nullptr;
  // Called after each alarm journal entry is committed, from the thread that
  // made it (a hook for live updates); must be thread-safe. May be empty.
  std::function<void(const nlohmann::json& event)> on_alarm_event;
  int alarm_tick_ms = 1000;     // shelve expiry is checked this often
  int stale_check_s = 30;       // stale data is checked this often
};

// A request refused for the state it finds: HTTP 409 (rest.md).
class ConflictError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
// Something the request names does not exist: HTTP 404.
class NotFoundError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};
// What the request names was dropped by the pump's retention policy: HTTP
// 410 (docs/storage.md "Retention").
class GoneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class AnalysisService {
 public:
  explicit AnalysisService(AnalysisOptions options);
  ~AnalysisService();  // stops and joins
  AnalysisService(const AnalysisService&) = delete;
  AnalysisService& operator=(const AnalysisService&) = delete;

  // With workers: requeues jobs whose lease expired, queues every run that
  // lacks its analysis, evaluates pending alarms, starts the workers and
  // the lease thread. Always: the thread that queues notified runs.
  void start();
  // Finishes nothing new: running jobs are abandoned after their current
  // stage and given back (queued again at once); joins. Idempotent.
  void stop();

  // A run was stored complete (called by ingest after its commit): queues
  // its analysis if the ingest has not (queue_run_analysis), wakes the
  // workers.
  void notify_run_complete(const std::string& run_id);

  // PUT .../model: a new version; InputError (400) when the plant does not
  // parse, naming the field.
  int put_model(const std::string& pump_id, const std::string& plant_json, const std::string& by);
  struct ReferenceReply {
    std::int64_t job_id;
    int reference_version;
  };
  // PUT .../reference: InputError for bad runs, NotFoundError for an
  // unknown pump, ConflictError when the pump has no model.
  ReferenceReply put_reference(const std::string& pump_id, const std::vector<std::string>& run_ids, const std::string& by);
  // POST .../explain: the explain job of the run against the current model.
  std::int64_t request_explain(const std::string& run_id, const std::string& by);
  // POST /jobs/{id}/adopt: a done explain job's improved model becomes the
  // pump's next model version. Returns it.
  int adopt_explained_model(std::int64_t job_id, const std::string& by);
  // POST /jobs/{id}/cancel: a queued job is cancelled (ConflictError otherwise).
  void cancel_job(std::int64_t job_id, const std::string& by);

  // Alarms (rest.md "Alarms"). The effective default rules (a full rule set).
  const nlohmann::json& alarm_defaults() const;
  // PUT .../alarm-rules: InputError naming the field; returns the pump's
  // effective rules.
  nlohmann::json put_alarm_rules(const std::string& pump_id, const nlohmann::json& body, const std::string& by);
  // Each returns the alarm after the transition: NotFoundError for an
  // unknown alarm, ConflictError where its state allows no such transition,
  // InputError for a bad argument (a missing comment, minutes out of range).
  nlohmann::json acknowledge_alarm(std::int64_t alarm_id, const std::string& by, const std::string& comment);
  nlohmann::json shelve_alarm(std::int64_t alarm_id, std::int64_t minutes, const std::string& by, const std::string& comment);
  nlohmann::json unshelve_alarm(std::int64_t alarm_id, const std::string& by, const std::string& comment);
  nlohmann::json reset_alarm(std::int64_t alarm_id, const std::string& by, const std::string& comment);

  // Jobs finished, failed, CPU seconds by kind (for health and metrics).
  nlohmann::json counters() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// The analysis job of a complete identification run against its pump's
// current model and reference versions (and the reference job it depends
// on), on `h` and inside its transaction if one is open (the ingest calls it
// in the commit that makes the run complete). Idempotent; false when
// nothing was queued (no model, not a complete identification run, queued
// before). Throws InputError for an unknown run.
bool queue_run_analysis(storage::Historian& h, const std::string& run_id);

}  // namespace ambdiag::server
