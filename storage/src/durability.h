// Private to ambdiag_storage: which of a writer's commits are durable
// (Historian::commit_generation, durable_generation, on_durable;
// docs/storage.md "Durability"). SQLite learns it from its checkpoints
// (background_checkpoint.h); on PostgreSQL a commit is durable when it
// returns (synchronous_commit on), so each commit is durable at once.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>

#include "ambdiag/storage/historian.h"
#include "sql/connection.h"

namespace ambdiag::storage::detail {

class Durability {
 public:
  virtual ~Durability() = default;
  virtual CheckpointStats stats() const = 0;
  virtual std::uint64_t commit_generation() const = 0;
  virtual std::uint64_t durable_generation() const = 0;
  // Called with each new durable number; nullptr removes it (waiting for a
  // call in progress).
  virtual void on_durable(std::function<void(std::uint64_t)> listener) = 0;
};

// Every commit of `db` is durable when COMMIT returns: the listener is
// called right after it, in the committing thread (as SQLite's with
// sync_commits). Registers itself as db's commit listener while it lives.
class DurableAtCommit final : public Durability {
 public:
  explicit DurableAtCommit(Connection& db) : db_(db) {
    db_.set_on_commit([this] {
      const std::uint64_t g = ++generation_;
      std::lock_guard lock(listener_mu_);
      if (listener_) listener_(g);
    });
  }
  ~DurableAtCommit() override { db_.set_on_commit(nullptr); }
  DurableAtCommit(const DurableAtCommit&) = delete;
  DurableAtCommit& operator=(const DurableAtCommit&) = delete;

  CheckpointStats stats() const override {
    CheckpointStats s;
    s.commit_generation = s.durable_generation = generation_.load();
    return s;
  }
  std::uint64_t commit_generation() const override { return generation_.load(); }
  std::uint64_t durable_generation() const override { return generation_.load(); }
  void on_durable(std::function<void(std::uint64_t)> listener) override {
    std::lock_guard lock(listener_mu_);
    listener_ = std::move(listener);
  }

 private:
  Connection& db_;
  std::atomic<std::uint64_t> generation_{1};  // 1: the state found at start, as SQLite's
  std::mutex listener_mu_;
  std::function<void(std::uint64_t)> listener_;
};

}  // namespace ambdiag::storage::detail
