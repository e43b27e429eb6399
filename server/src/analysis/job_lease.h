// The leases of the jobs this process runs (docs/service.md "Several
// servers"): a thread of normal priority with its own connection renews
// each held job's lease every lease/3 (not only at progress reports: one
// diagnosis step can take seconds, and the workers run at SCHED_IDLE), and
// every lease/2 queues again the jobs of any process whose lease expired
// (their worker was killed or is paused), so another worker takes them
// within about a lease and a half.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

class WorkSignal;

class LeaseKeeper {
 public:
  LeaseKeeper(const std::string& db_path, std::chrono::milliseconds lease, WorkSignal& work, bool verbose);
  ~LeaseKeeper();  // stops
  LeaseKeeper(const LeaseKeeper&) = delete;
  LeaseKeeper& operator=(const LeaseKeeper&) = delete;

  // Requeues what expired by now, then starts the thread.
  void start();
  void stop();  // idempotent; joins
  std::chrono::milliseconds lease() const { return lease_; }

  // Renews the attempt's lease until release(); the flag turns true when a
  // renewal is refused (the attempt no longer holds the job: its work is
  // lost, nothing it stores would be kept).
  std::shared_ptr<const std::atomic<bool>> hold(std::int64_t job_id, int attempt);
  void release(std::int64_t job_id);

 private:
  void loop();
  void renew_all();
  void requeue_expired();

  struct Held {
    int attempt = 0;
    std::shared_ptr<std::atomic<bool>> lost;
  };
  const std::chrono::milliseconds lease_;
  WorkSignal& work_;
  const bool verbose_;
  storage::Historian h_;  // the thread's (and start()'s, before it runs)
  std::mutex mu_;         // guards held_, stopping_
  std::condition_variable cv_;
  std::map<std::int64_t, Held> held_;
  bool stopping_ = false;
  std::thread thread_;
};

}  // namespace ambdiag::server::detail
