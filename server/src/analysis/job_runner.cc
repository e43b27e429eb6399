#include "job_runner.h"

#include <pthread.h>
#include <sched.h>

#include <chrono>
#include <cstring>
#include <ctime>
#include <thread>

#include "ambdiag/core/error.h"
#include "ambdiag/core/run_recording.h"
#include "ambdiag/server/events.h"
#include "run_analysis.h"
#include "trends/run_series.h"

namespace ambdiag::server::detail {

namespace {

using nlohmann::json;
using storage::Historian;

// Thrown from the progress callback when the attempt lost its job (cancelled,
// requeued, its lease expired) or the server stops: the work is abandoned,
// nothing stored.
struct Abandoned {};

// Attempts a job may lose to database failures before it is recorded failed.
constexpr int kMaxDatabaseAttempts = 5;

// SQLite lets one connection write at a time; under continuous ingest a
// job's write may wait past the busy timeout (StorageError). The result is
// worth a few more tries before the attempt is given up (it is then queued
// again at the next start).
template <class F>
auto with_retries(F&& write) {
  for (int attempt = 1;; ++attempt) {
    try {
      return write();
    } catch (const storage::StorageError&) {
      if (attempt == 5) throw;
      std::this_thread::sleep_for(std::chrono::milliseconds(200 * attempt));
    }
  }
}

// Workers compute at SCHED_IDLE, but a write transaction holds SQLite's one
// write lock: at idle priority a worker could be preempted inside it for as
// long as ingest keeps the CPUs busy, and ingest's next commit would wait
// for the lock (priority inversion). Writes therefore run at normal
// priority; the scope restores the thread's policy after.
class NormalPriorityScope {
 public:
  NormalPriorityScope() {
    sched_param p{};
    if (pthread_getschedparam(pthread_self(), &policy_, &p) == 0 && policy_ == SCHED_IDLE) {
      const sched_param normal{};
      raised_ = pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal) == 0;
    }
  }
  ~NormalPriorityScope() {
    if (!raised_) return;
    const sched_param p{};
    pthread_setschedparam(pthread_self(), policy_, &p);
  }
  NormalPriorityScope(const NormalPriorityScope&) = delete;
  NormalPriorityScope& operator=(const NormalPriorityScope&) = delete;

 private:
  int policy_ = SCHED_OTHER;
  bool raised_ = false;
};

double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// A complete stored run's header as a recording without samples.
RunRecording load_run_header(const storage::RunInfo& info) {
  if (info.status != storage::RunStatus::complete)
    throw InputError("run '" + info.run_id + "' is " + storage::to_string(info.status) +
                     (info.status_reason.empty() ? "" : " (" + info.status_reason + ")"));
  try {
    return run_from_json(json::parse(info.header_json));
  } catch (const json::exception& e) {
    throw InputError("run '" + info.run_id + "': run.json: " + e.what());
  }
}

storage::RunInfo find_run(Historian& h, const std::string& run_id) {
  auto info = h.find_run(run_id);
  if (!info) throw InputError("run '" + run_id + "' is not in the historian");
  return std::move(*info);
}

// The stored run as a recording: its run.json and its samples (InputError
// naming retention when they were dropped).
RunRecording load_run(Historian& h, const std::string& run_id) {
  RunRecording run = load_run_header(find_run(h, run_id));
  const std::string bytes = h.read_samples(run_id);
  if (bytes.size() % sizeof(float) != 0) throw InputError("run '" + run_id + "': samples are not whole float32 values");
  run.samples.resize(bytes.size() / sizeof(float));
  std::memcpy(run.samples.data(), bytes.data(), bytes.size());
  try {
    run.validate();
  } catch (const InputError& e) {
    rethrow_with_context(e, "run '" + run_id + "'");
  }
  return run;
}

// The FRF the run's newest done analysis kept, with that job's id.
std::optional<std::pair<FrfData, std::int64_t>> kept_frf(Historian& h, const std::string& run_id) {
  storage::JobFilter f;
  f.run_id = run_id;
  f.kind = "analysis";
  f.status = storage::JobStatus::done;
  f.limit = 1;
  for (const auto& j : h.list_jobs(f))
    if (auto a = h.find_artifact(j.job_id, "frf.csv"))
      return std::pair{parse_frf_csv(a->data, "frf.csv of job " + std::to_string(j.job_id)), j.job_id};
  return std::nullopt;
}

// Neither samples nor an FRF: the run cannot be analysed again.
[[noreturn]] void throw_nothing_left(const storage::RunInfo& info) {
  throw InputError("run '" + info.run_id + "': its samples were dropped by retention at " +
                   info.samples_dropped_at.value_or("?") +
                   (info.frf_dropped_at ? " and its FRF at " + *info.frf_dropped_at
                                        : std::string(" and no analysis of it kept an FRF")) +
                   ": it cannot be analysed again (its earlier results are kept)");
}

// A run's FRF: the one its analysis kept, else estimated now.
FrfData run_frf(Historian& h, const std::string& run_id) {
  if (auto kept = kept_frf(h, run_id)) return std::move(kept->first);
  const auto info = find_run(h, run_id);
  if (info.samples_dropped_at) throw_nothing_left(info);
  return estimate_run_frf(load_run(h, run_id), nullptr);
}

// An analysis of a run whose samples retention dropped: from the FRF an
// earlier analysis kept.
JobOutput analyse_kept_frf(Historian& h, const storage::RunInfo& info, const PlantModel& plant,
                           const OperatingReference* ref, double alpha, const ProgressFn& progress) {
  auto kept = kept_frf(h, info.run_id);
  if (!kept) throw_nothing_left(info);
  const json summary = {{"source", "frf.csv of analysis job " + std::to_string(kept->second)},
                        {"samples_dropped_at", *info.samples_dropped_at},
                        {"lines", kept->first.freq_hz.size()},
                        {"entries", kept->first.entries.size()}};
  return analyse_frf(plant, load_run_header(info), std::move(kept->first), summary, ref, alpha, progress);
}

PlantModel job_plant(Historian& h, const storage::Job& job) {
  const auto m = h.find_model(job.key.pump_id, job.key.model_version);
  if (!m) throw InputError("pump '" + job.key.pump_id + "' has no model version " + std::to_string(job.key.model_version));
  return plant_from_text(m->plant_json, "model version " + std::to_string(m->version) + " of pump " + job.key.pump_id);
}

}  // namespace

void JobCounters::attach(MetricsRegistry& registry) {
  durations_ = &registry.histogram("ambdiag_job_duration_seconds",
                                   "Wall time of a job attempt from claim to stored result, by kind and outcome (done or failed).",
                                   {"kind", "outcome"}, default_seconds_buckets());
  cpu_ = &registry.counter("ambdiag_job_cpu_seconds_total", "CPU seconds of the worker threads in jobs, by kind.", {"kind"});
}

void JobCounters::finished(const std::string& kind, bool ok, double cpu_s, double wall_s) {
  if (durations_) durations_->with({kind, ok ? "done" : "failed"}).observe(wall_s);
  if (cpu_) cpu_->with({kind}).inc(cpu_s);
  std::lock_guard l(mu_);
  auto& k = kinds_[kind];
  (ok ? k.done : k.failed) += 1;
  k.cpu_s += cpu_s;
  k.wall_s += wall_s;
}

json JobCounters::to_json() const {
  std::lock_guard l(mu_);
  json j = json::object();
  for (const auto& [name, k] : kinds_)
    j[name] = {{"done", k.done}, {"failed", k.failed}, {"cpu_s", k.cpu_s}, {"wall_s", k.wall_s}};
  return j;
}

JobRunner::JobRunner(const AnalysisOptions& opt, std::string name, JobCounters& counters, WorkSignal& work,
                     const std::atomic<bool>& stop, LeaseKeeper& leases)
    : opt_(opt),
      name_(std::move(name)),
      counters_(counters),
      work_(work),
      stop_(stop),
      leases_(leases),
      h_(Historian::open(opt.db_path, Historian::Mode::write)),
      alarms_(opt.alarm_defaults, opt.on_alarm_event) {}

void JobRunner::evaluate_alarms(const std::string& pump_id) {
  try {
    const NormalPriorityScope normal;
    with_retries([&] { return alarms_.catch_up(h_, pump_id); });
  } catch (const std::exception& e) {  // evaluated at the next finished analysis or start
    std::fprintf(stderr, "ambdiag serve: %s: alarm evaluation of pump %s: %s\n", name_.c_str(), pump_id.c_str(), e.what());
  }
}

void JobRunner::run() {
  while (!stop_) {
    const auto seen = work_.generation();
    bool ran = false;
    try {
      ran = run_one();
    } catch (const std::exception& e) {  // the database itself failed: try again later
      std::fprintf(stderr, "ambdiag serve: %s: %s\n", name_.c_str(), e.what());
    }
    if (!ran && !stop_) work_.wait_for(std::chrono::milliseconds(1000), seen);
  }
}

const OperatingReference& JobRunner::reference_of(std::int64_t reference_job) {
  if (!cached_reference_ || cached_reference_->first != reference_job) {
    cached_reference_.reset();
    const auto art = h_.find_artifact(reference_job, "reference.json");
    if (!art) throw InputError("reference job " + std::to_string(reference_job) + " kept no reference");
    cached_reference_.emplace(reference_job, operating_reference_from_json(art->data));
  }
  return cached_reference_->second;
}

bool JobRunner::run_one() {
  const auto job = [&] {
    const NormalPriorityScope normal;
    return h_.claim_job(name_, {}, leases_.lease());
  }();
  if (!job) return false;
  const auto lost = leases_.hold(job->job_id, job->attempts);
  try {
    execute(*job, *lost);
  } catch (...) {
    leases_.release(job->job_id);
    throw;
  }
  leases_.release(job->job_id);
  return true;
}

void JobRunner::execute(const storage::Job& job, const std::atomic<bool>& lost) {
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = thread_cpu_s();
  auto last_report = wall0;
  double last_share = 0.0;
  const ProgressFn progress = [&](double share) {
    if (stop_ || lost) throw Abandoned{};
    const auto now = std::chrono::steady_clock::now();
    if (share - last_share < 0.05 && now - last_report < std::chrono::seconds(1)) return;
    last_share = share;
    last_report = now;
    const NormalPriorityScope normal;
    if (!h_.set_job_progress(job.job_id, job.attempts, share)) throw Abandoned{};
  };
  const std::string what = job.key.kind + " job " + std::to_string(job.job_id) +
                           (job.key.run_id.empty() ? " of pump " + job.key.pump_id : " of run " + job.key.run_id);
  bool ok = false;
  std::optional<std::string> failure;  // recorded as the job's error
  std::string summary;
  // "job.done" / "job.failed" (GET /api/v1/events), stored with the result
  // or the failure in one transaction: announced exactly when stored.
  const auto event = [&](bool done, const std::string& error) {
    json d = {{"job_id", job.job_id}, {"kind", job.key.kind}, {"pump_id", job.key.pump_id}, {"status", done ? "done" : "failed"},
              {"model_version", job.key.model_version}, {"reference_version", job.key.reference_version}, {"summary", summary}};
    if (!job.key.run_id.empty()) d["run_id"] = job.key.run_id;
    if (!done) d["error"] = error;
    h_.append_event(done ? "job.done" : "job.failed", job.key.pump_id, event_data(d));
  };
  // `write` (finish or fail, fenced) and its event in one transaction.
  const auto store = [&](const auto& write, bool done, const std::string& error) {
    const NormalPriorityScope normal;
    return with_retries([&] {
      auto batch = h_.write_batch();
      if (!write()) return false;
      event(done, error);
      batch.commit();
      return true;
    });
  };
  const auto record_failure = [&](const std::string& error) {
    try {
      if (store([&] { return h_.fail_job(job.job_id, job.attempts, error); }, false, error)) failure = error;
    } catch (const std::exception& e2) {
      std::fprintf(stderr, "ambdiag serve: %s: cannot record the failure: %s\n", what.c_str(), e2.what());
    }
  };
  try {
    JobOutput out;
    const PlantModel plant = job_plant(h_, job);
    if (job.key.kind == "analysis") {
      const OperatingReference* ref = nullptr;
      if (job.key.reference_version > 0) {
        if (!job.depends_on) throw InputError("no reference job for reference version " + std::to_string(job.key.reference_version));
        ref = &reference_of(*job.depends_on);
      }
      const auto info = find_run(h_, job.key.run_id);
      out = info.samples_dropped_at ? analyse_kept_frf(h_, info, plant, ref, opt_.alpha, progress)
                                    : analyse_run(plant, load_run(h_, job.key.run_id), ref, opt_.alpha, progress);
      const auto& d = out.result["detection"];
      summary = d.is_null() ? "no reference" : (d["detected"].get<bool>() ? "CHANGE DETECTED" : "no change");
      if (!out.result["diagnosis"].is_null() && !out.result["diagnosis"]["faults"].empty())
        summary += ", first " + out.result["diagnosis"]["faults"][0]["fault"].get<std::string>();
    } else if (job.key.kind == "reference") {
      const auto ref = h_.find_reference(job.key.pump_id, job.key.reference_version);
      if (!ref) throw InputError("pump '" + job.key.pump_id + "' has no reference version " + std::to_string(job.key.reference_version));
      std::vector<FrfData> frfs;
      for (size_t i = 0; i < ref->run_ids.size(); ++i) {
        frfs.push_back(run_frf(h_, ref->run_ids[i]));
        progress(0.8 * static_cast<double>(i + 1) / static_cast<double>(ref->run_ids.size()));
      }
      out = learn_reference(plant, frfs, ref->run_ids, [&](double s) { progress(0.8 + 0.2 * s); });
      summary = std::to_string(frfs.size()) + " runs";
    } else if (job.key.kind == "explain") {
      out = explain_run(plant, run_frf(h_, job.key.run_id), progress);
      summary = std::to_string(out.result.value("explanations", json::array()).size()) + " explanations";
    } else {
      throw InputError("unknown job kind '" + job.key.kind + "'");
    }
    const double cpu = thread_cpu_s() - cpu0;
    out.result["cpu_s"] = cpu;
    const std::string result_text = out.result.dump();
    // An analysis' trend values go in with its result (one transaction).
    std::optional<std::vector<SeriesValue>> series;
    if (job.key.kind == "analysis") series = run_series(out.result);
    ok = store([&] { return h_.finish_job(job.job_id, job.attempts, result_text, out.artifacts, series); }, true, "");
    if (!ok) summary = "result refused: the attempt no longer holds the job";
  } catch (const Abandoned&) {
    summary = lost ? "abandoned: the attempt lost its job (lease expired, requeued or cancelled)" : "abandoned";
    // The process stops: the job goes back at once rather than when its lease ends.
    if (!lost) {
      try {
        const NormalPriorityScope normal;
        if (h_.release_job(job.job_id, job.attempts)) summary += ", queued again";
      } catch (const std::exception&) {  // then its lease expires
      }
    }
  } catch (const storage::StorageError& e) {
    // The database failed, not the job (e.g. PostgreSQL restarting under a
    // read of the run): the attempt goes back to the queue, as a killed
    // worker's does, rather than failing the run's analysis for good. A job
    // that keeps failing so (kMaxDatabaseAttempts) is recorded failed.
    if (job.attempts < kMaxDatabaseAttempts) {
      summary = std::string("the database failed: ") + e.what();
      try {
        const NormalPriorityScope normal;
        if (h_.release_job(job.job_id, job.attempts)) summary += "; queued again";
      } catch (const std::exception&) {  // then its lease expires and any worker requeues it
        summary += "; queued again when its lease expires";
      }
    } else {
      summary = std::string("failed: ") + e.what();
      record_failure(e.what());
    }
  } catch (const std::exception& e) {
    summary = std::string("failed: ") + e.what();
    record_failure(e.what());
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  const double cpu = thread_cpu_s() - cpu0;
  counters_.finished(job.key.kind, ok, cpu, wall);
  // Done or failed (a failed analysis is poor data): the alarms follow.
  if (job.key.kind == "analysis" && (ok || failure)) evaluate_alarms(job.key.pump_id);
  if (opt_.verbose)
    std::fprintf(stderr, "ambdiag serve: %s (attempt %d): %s, %.2f s, %.2f CPU-s\n", what.c_str(), job.attempts,
                 summary.c_str(), wall, cpu);
}

}  // namespace ambdiag::server::detail
