// One worker thread of the analysis service: claims jobs from the
// historian's queue with a lease (job_lease.h renews it) and runs them
// (run_analysis.h), storing each result with its files and its event in
// one transaction, fenced by the attempt number and the lease.
#pragma once

#include <atomic>
#include <condition_variable>
#include <map>
#include <optional>
#include <utility>
#include <mutex>
#include <string>

#include <nlohmann/json.hpp>

#include "alarms/alarm_evaluator.h"
#include "analysis/job_lease.h"
#include "ambdiag/algorithms/diagnosis/operating_reference.h"
#include "ambdiag/server/analysis_service.h"
#include "ambdiag/server/metrics.h"
#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

// Wakes idle workers when work was queued (they also poll every second:
// another process may have queued it).
class WorkSignal {
 public:
  void notify() {
    { std::lock_guard l(mu_); ++gen_; }
    cv_.notify_one();
  }
  void notify_all() {
    { std::lock_guard l(mu_); ++gen_; }
    cv_.notify_all();
  }
  void wait_for(std::chrono::milliseconds d, std::uint64_t seen) {
    std::unique_lock l(mu_);
    cv_.wait_for(l, d, [&] { return gen_ != seen; });
  }
  std::uint64_t generation() {
    std::lock_guard l(mu_);
    return gen_;
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  std::uint64_t gen_ = 0;
};

class JobCounters {
 public:
  // Also into `registry` from now on: a duration histogram by kind and
  // outcome, CPU seconds by kind.
  void attach(MetricsRegistry& registry);
  void finished(const std::string& kind, bool ok, double cpu_s, double wall_s);
  nlohmann::json to_json() const;

 private:
  MetricFamily<Histogram>* durations_ = nullptr;
  MetricFamily<Counter>* cpu_ = nullptr;
  struct Kind {
    std::int64_t done = 0, failed = 0;
    double cpu_s = 0, wall_s = 0;
  };
  mutable std::mutex mu_;
  std::map<std::string, Kind> kinds_;
};

class JobRunner {
 public:
  JobRunner(const AnalysisOptions& opt, std::string name, JobCounters& counters, WorkSignal& work,
            const std::atomic<bool>& stop, LeaseKeeper& leases);
  // Until stop: claim, run, store; wait for work when the queue is empty.
  void run();
  // Claims and runs one job if there is one; false when the queue was empty.
  bool run_one();

 private:
  void execute(const storage::Job& job, const std::atomic<bool>& lost);
  // The reference a reference job learnt. The last one is kept: a pump's
  // runs come in a row after its reference changes, and reading and parsing
  // the 1.7 MB document (17 ms) again for each would add 3 % to every run.
  const OperatingReference& reference_of(std::int64_t reference_job);
  // After an analysis ended: the pump's alarms (alarm_evaluator.h says in
  // which order and how a crash is recovered from).
  void evaluate_alarms(const std::string& pump_id);
  const AnalysisOptions& opt_;
  std::string name_;
  JobCounters& counters_;
  WorkSignal& work_;
  const std::atomic<bool>& stop_;
  LeaseKeeper& leases_;
  storage::Historian h_;
  std::optional<std::pair<std::int64_t, OperatingReference>> cached_reference_;
  AlarmEvaluator alarms_;
};

}  // namespace ambdiag::server::detail
