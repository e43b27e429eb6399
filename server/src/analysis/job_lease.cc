#include "job_lease.h"

#include <cstdio>
#include <vector>

#include "job_runner.h"

namespace ambdiag::server::detail {

LeaseKeeper::LeaseKeeper(const std::string& db_path, std::chrono::milliseconds lease, WorkSignal& work, bool verbose)
    : lease_(std::max(lease, std::chrono::milliseconds(30))),
      work_(work),
      verbose_(verbose),
      h_(storage::Historian::open(db_path, storage::Historian::Mode::write)) {}

LeaseKeeper::~LeaseKeeper() { stop(); }

void LeaseKeeper::start() {
  if (thread_.joinable()) return;
  requeue_expired();
  thread_ = std::thread([this] { loop(); });
}

void LeaseKeeper::stop() {
  {
    std::lock_guard l(mu_);
    stopping_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::shared_ptr<const std::atomic<bool>> LeaseKeeper::hold(std::int64_t job_id, int attempt) {
  auto lost = std::make_shared<std::atomic<bool>>(false);
  std::lock_guard l(mu_);
  held_[job_id] = {attempt, lost};
  return lost;
}

void LeaseKeeper::release(std::int64_t job_id) {
  std::lock_guard l(mu_);
  held_.erase(job_id);
}

void LeaseKeeper::loop() {
  using clock = std::chrono::steady_clock;
  auto next_renew = clock::now() + lease_ / 3, next_requeue = clock::now() + lease_ / 2;
  std::unique_lock l(mu_);
  while (!stopping_) {
    cv_.wait_until(l, std::min(next_renew, next_requeue), [&] { return stopping_; });
    if (stopping_) break;
    l.unlock();
    const auto now = clock::now();
    if (now >= next_renew) {
      renew_all();
      next_renew = now + lease_ / 3;
    }
    if (now >= next_requeue) {
      requeue_expired();
      next_requeue = now + lease_ / 2;
    }
    l.lock();
  }
}

void LeaseKeeper::renew_all() {
  std::vector<std::pair<std::int64_t, Held>> held;
  {
    std::lock_guard l(mu_);
    held.assign(held_.begin(), held_.end());
  }
  for (const auto& [job_id, h] : held) {
    try {
      if (!h_.renew_job_lease(job_id, h.attempt, lease_)) h.lost->store(true);
    } catch (const std::exception& e) {  // busy past the timeout: the next renewal tries again
      std::fprintf(stderr, "ambdiag serve: cannot renew the lease of job %lld: %s\n", static_cast<long long>(job_id), e.what());
    }
  }
}

void LeaseKeeper::requeue_expired() {
  try {
    const auto r = h_.requeue_expired_jobs();
    if (r.requeued > 0) work_.notify_all();
    if (verbose_ && (r.requeued > 0 || r.failed > 0))
      std::fprintf(stderr, "ambdiag serve: %d jobs whose lease expired queued again, %d failed after their last attempt\n",
                   r.requeued, r.failed);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "ambdiag serve: cannot requeue expired jobs: %s\n", e.what());
  }
}

}  // namespace ambdiag::server::detail
