#include "reader_pool.h"

namespace ambdiag::server::detail {

ReaderPool::ReaderPool(std::string db_path, int max_readers) : path_(std::move(db_path)), max_(max_readers) {
  // Opening one now reports a missing or foreign database at start-up.
  idle_.push_back(std::make_unique<storage::Historian>(storage::Historian::open(path_, storage::Historian::Mode::read)));
  opened_ = 1;
}

ReaderPool::Lease ReaderPool::acquire() {
  std::unique_lock lock(m_);
  cv_.wait(lock, [&] { return !idle_.empty() || opened_ < max_; });
  if (!idle_.empty()) {
    auto h = std::move(idle_.back());
    idle_.pop_back();
    return Lease(this, std::move(h));
  }
  ++opened_;
  lock.unlock();
  try {
    return Lease(this, std::make_unique<storage::Historian>(storage::Historian::open(path_, storage::Historian::Mode::read)));
  } catch (...) {
    std::lock_guard relock(m_);
    --opened_;
    cv_.notify_one();
    throw;
  }
}

ReaderPool::Lease::~Lease() {
  if (!h_) return;
  {
    std::lock_guard lock(pool_->m_);
    pool_->idle_.push_back(std::move(h_));
  }
  pool_->cv_.notify_one();
}

}  // namespace ambdiag::server::detail
