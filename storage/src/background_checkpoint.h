// Private to ambdiag_storage: copies the writer's write-ahead log into the
// database file from a thread and connection of its own (docs/storage.md,
// "Checkpoints"), so a commit never waits for a checkpoint's fsyncs; and
// tracks which of the writer's commits are durable (on disk for good, not
// only in the page cache): docs/storage.md, "Durability".
#pragma once

#include <sqlite3.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "ambdiag/storage/historian.h"
#include "durability.h"

namespace ambdiag::storage::detail {

class BackgroundCheckpoint final : public Durability {
 public:
  // Installs itself as `writer`'s WAL hook (which replaces SQLite's
  // automatic checkpoint): after a commit that leaves `trigger_pages` or
  // more in the log the thread checkpoints; should it fall behind until
  // `inline_pages` are in the log, the committing writer checkpoints itself,
  // so the log stays bounded either way. A commit not yet durable after
  // `durable_within` starts a checkpoint too (the time trigger).
  BackgroundCheckpoint(sqlite3* writer, std::string path, const CheckpointOptions& opt);
  ~BackgroundCheckpoint() override;  // finishes a running checkpoint, restores SQLite's automatic one
  BackgroundCheckpoint(const BackgroundCheckpoint&) = delete;
  BackgroundCheckpoint& operator=(const BackgroundCheckpoint&) = delete;

  CheckpointStats stats() const override;
  std::uint64_t commit_generation() const override { return committed_.load(); }
  std::uint64_t durable_generation() const override { return durable_.load(); }
  void on_durable(std::function<void(std::uint64_t)> listener) override;

 private:
  using Clock = std::chrono::steady_clock;
  static int on_commit(void* self, sqlite3* db, const char* schema, int pages);
  void loop();
  // One PASSIVE checkpoint on `db`; commits up to `through` are durable if
  // it left nothing in the log uncopied (see the .cc).
  void checkpoint(sqlite3* db, const char* schema, std::uint64_t through, bool background);
  void made_durable(std::uint64_t through);

  sqlite3* writer_;
  const std::string path_;
  const CheckpointOptions opt_;
  // Commit numbers: 1 is the state found at start (a process crash may have
  // left committed, unsynced transactions in the log), each commit adds 1.
  std::atomic<std::uint64_t> committed_{1}, durable_{0};
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool wanted_ = false, stop_ = false;
  std::optional<Clock::time_point> undurable_since_ = Clock::now();
  CheckpointStats stats_;
  std::mutex listener_mu_;  // held while the listener runs: on_durable() waits for a call in progress
  std::function<void(std::uint64_t)> listener_;
  std::thread thread_;
};

}  // namespace ambdiag::storage::detail
