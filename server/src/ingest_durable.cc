#include "ingest_durable.h"

#include <pthread.h>

namespace ambdiag::server::detail {

DurableAcks::DurableAcks(std::function<void(const AckMsg&)> send) : send_(std::move(send)) {
  thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "ambdiag-durable");
    loop();
  });
}

DurableAcks::~DurableAcks() {
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void DurableAcks::hold(uint64_t generation, std::vector<AckMsg> acks) {
  if (acks.empty()) return;
  {
    std::lock_guard lock(mu_);
    held_.emplace_back(generation, std::move(acks));
  }
  cv_.notify_all();
}

void DurableAcks::durable(uint64_t generation) {
  {
    std::lock_guard lock(mu_);
    if (generation <= durable_) return;
    durable_ = generation;
  }
  cv_.notify_all();
}

void DurableAcks::drain(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mu_);
  drained_cv_.wait_for(lock, timeout, [&] { return held_.empty() && !sending_; });
}

void DurableAcks::loop() {
  std::unique_lock lock(mu_);
  for (;;) {
    cv_.wait(lock, [&] { return stop_ || (!held_.empty() && held_.front().first <= durable_); });
    if (stop_) return;
    std::vector<AckMsg> out;
    while (!held_.empty() && held_.front().first <= durable_) {
      for (auto& a : held_.front().second) out.push_back(std::move(a));
      held_.pop_front();
    }
    sending_ = true;
    lock.unlock();
    for (const auto& a : out) send_(a);
    lock.lock();
    sending_ = false;
    if (held_.empty()) drained_cv_.notify_all();
  }
}

}  // namespace ambdiag::server::detail
