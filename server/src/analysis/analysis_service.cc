#include "ambdiag/server/analysis_service.h"

#include <pthread.h>
#include <sched.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstring>
#include <ctime>
#include <deque>
#include <mutex>
#include <optional>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/server/events.h"
#include "alarms/alarm_rules.h"
#include "alarms/alarm_service.h"
#include "ambdiag/storage/historian.h"
#include "job_lease.h"
#include "job_runner.h"
#include "run_analysis.h"
#include "trends/run_series.h"
#include "views.h"

namespace ambdiag::server {

using storage::Historian;
using storage::JobKey;

namespace {

// The pump's current versions: (model, reference; 0 for none). nullopt
// without a model: nothing of the pump is analysed.
std::optional<std::pair<int, int>> current_versions(Historian& h, const std::string& pump_id) {
  const auto model = h.find_model(pump_id);
  if (!model) return std::nullopt;
  const auto ref = h.find_reference(pump_id);
  return std::pair{model->version, ref ? ref->version : 0};
}

// One analysis job for the run against the pump's versions (m, r) (and the
// reference job it needs). Idempotent.
bool schedule_run(Historian& h, const storage::RunInfo& run, int m, int r) {
  if (run.status != storage::RunStatus::complete || run.kind != "identification") return false;
  const JobKey key{"analysis", run.pump_id, run.run_id, m, r};
  if (h.find_job(key)) return false;
  std::optional<std::int64_t> depends;
  if (r > 0) depends = h.enqueue_job(JobKey{"reference", run.pump_id, "", m, r}).first;
  return h.enqueue_job(key, "{}", depends).second;
}

}  // namespace

bool queue_run_analysis(Historian& h, const std::string& run_id) {
  const auto run = h.find_run(run_id);
  if (!run) throw InputError("queue_run_analysis: unknown run '" + run_id + "'");
  const auto v = current_versions(h, run->pump_id);
  return v && schedule_run(h, *run, v->first, v->second);
}

struct AnalysisService::Impl {
  AnalysisOptions opt;
  std::mutex ctl_mu;               // guards ctl: the connection of REST writes and the scheduler
  std::optional<Historian> ctl;
  detail::JobCounters counters;

  std::mutex mu;                   // guards pending, stopping
  std::condition_variable cv;      // scheduler: a run to schedule, or stop
  std::deque<std::string> pending;
  bool stopping = false;
  std::atomic<bool> stop_flag{false};
  detail::WorkSignal work;         // wakes idle workers when jobs are queued
  std::thread scheduler;
  std::vector<std::thread> workers;

  std::optional<detail::AlarmService> alarms;
  std::optional<detail::LeaseKeeper> leases;  // with workers

  explicit Impl(AnalysisOptions o) : opt(std::move(o)) {
    if (opt.metrics) counters.attach(*opt.metrics);
    // The built-in rules with the server's own over them, validated now: a
    // bad file stops the server at its start, not at its first run.
    const auto& given = opt.alarm_defaults;
    opt.alarm_defaults = detail::merged_rule_set_json(detail::default_rule_set_json(),
                                                      given.is_null() ? nlohmann::json::object() : given, "alarm defaults");
  }

  // `write` and the event announcing it ("model.new", ...) in one
  // transaction on ctl. Caller holds ctl_mu.
  template <class F>
  auto announced(const std::string& type, const std::string& pump_id, F&& write) {
    auto batch = ctl->write_batch();
    auto [value, data] = write();
    ctl->append_event(type, pump_id, event_data(data));
    batch.commit();
    return value;
  }

  // Every run of the pump against its current versions; what older versions
  // still had queued is cancelled. Caller holds ctl_mu.
  int schedule_pump_locked(const std::string& pump_id) {
    const auto v = current_versions(*ctl, pump_id);
    if (!v) return 0;
    const auto [m, r] = *v;
    for (const char* kind : {"analysis", "reference"}) ctl->cancel_superseded_jobs(pump_id, kind, m, r);
    int n = 0;
    for (const auto& run : ctl->list_runs(pump_id)) n += schedule_run(*ctl, run, m, r) ? 1 : 0;
    return n;
  }

  void scheduler_loop() {
    for (;;) {
      std::string run_id;
      {
        std::unique_lock lock(mu);
        cv.wait(lock, [&] { return stopping || !pending.empty(); });
        if (stopping) return;
        run_id = std::move(pending.front());
        pending.pop_front();
      }
      try {
        std::lock_guard lock(ctl_mu);
        queue_run_analysis(*ctl, run_id);  // usually the ingest's commit has
      } catch (const std::exception& e) {
        std::fprintf(stderr, "ambdiag serve: cannot queue the analysis of run %s: %s\n", run_id.c_str(), e.what());
      }
      work.notify();
    }
  }
};

AnalysisService::AnalysisService(AnalysisOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {
  impl_->ctl.emplace(Historian::open(impl_->opt.db_path, Historian::Mode::write));
  impl_->alarms.emplace(impl_->opt.db_path, impl_->opt.alarm_defaults, impl_->opt.on_alarm_event, impl_->opt.alarm_tick_ms,
                        impl_->opt.stale_check_s);
}

AnalysisService::~AnalysisService() { stop(); }

void AnalysisService::start() {
  auto& I = *impl_;
  if (!I.workers.empty() || I.scheduler.joinable()) return;
  I.scheduler = std::thread([&I] { I.scheduler_loop(); });
  if (I.opt.workers <= 0) return;  // this process runs no jobs
  // What another process may be running is left to its lease; what expired
  // (a dead server's) is queued again now.
  I.leases.emplace(I.opt.db_path, I.opt.job_lease, I.work, I.opt.verbose);
  // A database restarting at this moment (a transaction's connection
  // closed under it) is not a reason to stop: the start-up's transactions
  // are tried again for up to 20 s. Each step may run again: the leases'
  // and the alarms' threads start only once their first transaction passed.
  for (int attempt = 1;; ++attempt) {
    try {
      I.leases->start();
      {
        std::lock_guard lock(I.ctl_mu);
        // Trend points of analyses stored before schema v5 (or without them).
        const int backfilled = I.ctl->backfill_series([](const std::string& result) {
          return detail::run_series(nlohmann::json::parse(result, nullptr, false));
        });
        if (I.opt.verbose && backfilled > 0)
          std::fprintf(stderr, "ambdiag serve: trend points of %d analysed runs filled in\n", backfilled);
        int queued = 0;
        for (const auto& p : I.ctl->list_pumps()) queued += I.schedule_pump_locked(p.pump_id);
        if (I.opt.verbose && queued > 0) std::fprintf(stderr, "ambdiag serve: %d runs queued for analysis\n", queued);
      }
      I.alarms->start();
      break;
    } catch (const storage::StorageError& e) {
      if (attempt >= 40) throw;
      std::fprintf(stderr, "ambdiag serve: analysis start: %s; trying again\n", e.what());
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
  }
  const std::string prefix = I.opt.instance.empty() ? "" : I.opt.instance + "/";
  for (int k = 0; k < I.opt.workers; ++k) {
    I.workers.emplace_back([&I, k, prefix] {
      if (I.opt.idle_priority) {
        // Analysis takes only what ingest and REST leave: a job is minutes
        // late at worst, a block never is.
        sched_param p{};
        pthread_setschedparam(pthread_self(), SCHED_IDLE, &p);
      }
      // The worker's connection: a database restarting right now (its
      // connections closed) is waited out, not a reason to end the process.
      const std::string name = prefix + "worker-" + std::to_string(k);
      std::optional<detail::JobRunner> runner;
      while (!runner && !I.stop_flag) {
        try {
          runner.emplace(I.opt, name, I.counters, I.work, I.stop_flag, *I.leases);
        } catch (const std::exception& e) {
          std::fprintf(stderr, "ambdiag serve: %s: cannot open the historian: %s; trying again\n", name.c_str(), e.what());
          std::this_thread::sleep_for(std::chrono::milliseconds(500));
        }
      }
      if (runner) runner->run();
    });
  }
}

void AnalysisService::stop() {
  auto& I = *impl_;
  {
    std::lock_guard lock(I.mu);
    I.stopping = true;
  }
  I.stop_flag = true;
  I.cv.notify_all();
  I.work.notify_all();
  if (I.scheduler.joinable()) I.scheduler.join();
  for (auto& t : I.workers) t.join();
  I.workers.clear();
  if (I.leases) I.leases->stop();
  if (I.alarms) I.alarms->stop();
}

void AnalysisService::notify_run_complete(const std::string& run_id) {
  {
    std::lock_guard lock(impl_->mu);
    impl_->pending.push_back(run_id);
  }
  impl_->cv.notify_one();
}

int AnalysisService::put_model(const std::string& pump_id, const std::string& plant_json, const std::string& by) {
  detail::plant_from_text(plant_json, "model of pump " + pump_id);  // InputError names the field
  std::lock_guard lock(impl_->ctl_mu);
  const int version = impl_->announced("model.new", pump_id, [&] {
    const int v = impl_->ctl->put_model(pump_id, plant_json, by);
    return std::pair{v, nlohmann::json{{"pump_id", pump_id}, {"model_version", v}, {"by", by}}};
  });
  impl_->schedule_pump_locked(pump_id);
  impl_->work.notify_all();
  return version;
}

AnalysisService::ReferenceReply AnalysisService::put_reference(const std::string& pump_id,
                                                               const std::vector<std::string>& run_ids,
                                                               const std::string& by) {
  std::lock_guard lock(impl_->ctl_mu);
  auto& h = *impl_->ctl;
  const auto model = h.find_model(pump_id);
  if (!model && !h.find_pump(pump_id)) throw NotFoundError("no pump '" + pump_id + "'");
  // The normal run-to-run scatter is learnt from the runs' differences.
  if (run_ids.size() < 2)
    throw InputError("reference: runs: " + std::to_string(run_ids.size()) + " run(s); at least 2 are needed to learn the normal scatter");
  if (!model) throw ConflictError("pump '" + pump_id + "' has no model: PUT /api/v1/pumps/{pump_id}/model first");
  const auto reply = impl_->announced("reference.new", pump_id, [&] {
    const int version = h.put_reference(pump_id, run_ids, by);
    const auto job = h.enqueue_job(JobKey{"reference", pump_id, "", model->version, version}).first;
    return std::pair{ReferenceReply{job, version},
                     nlohmann::json{{"pump_id", pump_id}, {"reference_version", version}, {"job_id", job}, {"by", by}}};
  });
  impl_->schedule_pump_locked(pump_id);
  impl_->work.notify_all();
  return reply;
}

std::int64_t AnalysisService::request_explain(const std::string& run_id, const std::string&) {
  std::lock_guard lock(impl_->ctl_mu);
  auto& h = *impl_->ctl;
  const auto run = h.find_run(run_id);
  if (!run) throw NotFoundError("no run '" + run_id + "'");
  if (run->status != storage::RunStatus::complete || run->kind != "identification")
    throw ConflictError("run '" + run_id + "' is " + storage::to_string(run->status) + " (" + run->kind +
                        "): only complete identification runs are explained");
  const auto model = h.find_model(run->pump_id);
  if (!model) throw ConflictError("pump '" + run->pump_id + "' has no model to explain the run against");
  const auto id = h.enqueue_job(JobKey{"explain", run->pump_id, run_id, model->version, 0}).first;
  impl_->work.notify_all();
  return id;
}

int AnalysisService::adopt_explained_model(std::int64_t job_id, const std::string& by) {
  std::lock_guard lock(impl_->ctl_mu);
  auto& h = *impl_->ctl;
  const auto job = h.find_job(job_id);
  if (!job) throw NotFoundError("no job " + std::to_string(job_id));
  if (job->key.kind != "explain" || job->status != storage::JobStatus::done)
    throw ConflictError("job " + std::to_string(job_id) + " is a " + job->key.kind + " job, " + storage::to_string(job->status) +
                        ": only a done explain job has a model to adopt");
  const auto art = h.find_artifact(job_id, "improved_model.json");
  if (!art) throw ConflictError("job " + std::to_string(job_id) + " kept no improved model");
  const int version = impl_->announced("model.new", job->key.pump_id, [&] {
    const int v = h.put_model(job->key.pump_id, art->data, by,
                              "adopted from explain job " + std::to_string(job_id) + " of run " + job->key.run_id);
    return std::pair{v, nlohmann::json{{"pump_id", job->key.pump_id}, {"model_version", v}, {"by", by}, {"adopted_from_job", job_id}}};
  });
  impl_->schedule_pump_locked(job->key.pump_id);
  impl_->work.notify_all();
  return version;
}

void AnalysisService::cancel_job(std::int64_t job_id, const std::string& by) {
  std::lock_guard lock(impl_->ctl_mu);
  auto& h = *impl_->ctl;
  const auto job = h.find_job(job_id);
  if (!job) throw NotFoundError("no job " + std::to_string(job_id));
  if (!h.cancel_job(job_id, "cancelled by " + (by.empty() ? std::string("an engineer") : by)))
    throw ConflictError("job " + std::to_string(job_id) + " is " + storage::to_string(job->status) + ": only a queued job can be cancelled");
}

const nlohmann::json& AnalysisService::alarm_defaults() const { return impl_->opt.alarm_defaults; }

nlohmann::json AnalysisService::put_alarm_rules(const std::string& pump_id, const nlohmann::json& body, const std::string& by) {
  return impl_->alarms->put_rules(pump_id, body, by);
}

nlohmann::json AnalysisService::acknowledge_alarm(std::int64_t alarm_id, const std::string& by, const std::string& comment) {
  return impl_->alarms->acknowledge(alarm_id, by, comment);
}

nlohmann::json AnalysisService::shelve_alarm(std::int64_t alarm_id, std::int64_t minutes, const std::string& by,
                                             const std::string& comment) {
  return impl_->alarms->shelve(alarm_id, minutes, by, comment);
}

nlohmann::json AnalysisService::unshelve_alarm(std::int64_t alarm_id, const std::string& by, const std::string& comment) {
  return impl_->alarms->unshelve(alarm_id, by, comment);
}

nlohmann::json AnalysisService::reset_alarm(std::int64_t alarm_id, const std::string& by, const std::string& comment) {
  return impl_->alarms->reset(alarm_id, by, comment);
}

nlohmann::json AnalysisService::counters() const { return impl_->counters.to_json(); }

}  // namespace ambdiag::server
