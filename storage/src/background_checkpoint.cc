#include "background_checkpoint.h"

#include <pthread.h>

#include <algorithm>

#include "sql/sqlite/sqlite_db.h"

namespace ambdiag::storage::detail {

BackgroundCheckpoint::BackgroundCheckpoint(sqlite3* writer, std::string path, const CheckpointOptions& opt)
    : writer_(writer), path_(std::move(path)), opt_(opt) {
  if (opt_.sync_commits) {  // every commit fsyncs the log: durable when it returns
    char* err = nullptr;
    if (sqlite3_exec(writer_, "PRAGMA synchronous = FULL", nullptr, nullptr, &err) != SQLITE_OK) {
      const std::string msg = err ? err : "?";
      sqlite3_free(err);
      throw StorageError(path_ + ": PRAGMA synchronous = FULL: " + msg);
    }
  }
  thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "ambdiag-ckpt");
    loop();
  });
  sqlite3_wal_hook(writer_, &BackgroundCheckpoint::on_commit, this);
}

BackgroundCheckpoint::~BackgroundCheckpoint() {
  sqlite3_wal_autocheckpoint(writer_, 1000);  // SQLite's default hook again
  if (opt_.sync_commits) sqlite3_exec(writer_, "PRAGMA synchronous = NORMAL", nullptr, nullptr, nullptr);
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

CheckpointStats BackgroundCheckpoint::stats() const {
  std::lock_guard lock(mu_);
  CheckpointStats s = stats_;
  s.commit_generation = committed_.load();
  s.durable_generation = durable_.load();
  return s;
}

void BackgroundCheckpoint::on_durable(std::function<void(std::uint64_t)> listener) {
  std::lock_guard lock(listener_mu_);
  listener_ = std::move(listener);
}

void BackgroundCheckpoint::made_durable(std::uint64_t through) {
  {
    std::lock_guard lock(mu_);
    if (through <= durable_.load()) return;
    durable_ = through;
    // Commits after `through` began no earlier than now: their clock starts here.
    undurable_since_ = committed_.load() > through ? std::optional(Clock::now()) : std::nullopt;
  }
  std::lock_guard lock(listener_mu_);
  if (listener_) listener_(durable_.load());
}

// Runs in the writer's thread, right after its commit.
int BackgroundCheckpoint::on_commit(void* self_ptr, sqlite3* db, const char* schema, int pages) {
  auto& self = *static_cast<BackgroundCheckpoint*>(self_ptr);
  const std::uint64_t gen = ++self.committed_;
  if (self.opt_.sync_commits) {
    // synchronous = FULL: the commit fsynced the log, with every frame before it.
    self.made_durable(gen);
  } else {
    std::lock_guard lock(self.mu_);
    if (!self.undurable_since_) {
      self.undurable_since_ = Clock::now();
      self.cv_.notify_one();  // the thread now waits for this commit's deadline
    }
  }
  if (pages >= self.opt_.inline_pages) {
    self.checkpoint(db, schema, gen, false);
  } else if (pages >= self.opt_.trigger_pages) {
    {
      std::lock_guard lock(self.mu_);
      self.wanted_ = true;
    }
    self.cv_.notify_one();
  }
  return SQLITE_OK;  // a failed checkpoint is counted, never the commit's failure
}

// A PASSIVE checkpoint first fsyncs the log, then copies frames into the
// database file, then fsyncs that file if it copied the whole log; it
// reports the frames in the log and those copied so far. When they are
// equal, every frame written before it started is on disk: in the synced
// file, or in the log it synced before copying. So every commit made before
// it started (`through`) is durable. When readers held old snapshots it
// copies less and may not sync at all: nothing is claimed, the thread
// tries again shortly.
void BackgroundCheckpoint::checkpoint(sqlite3* db, const char* schema, std::uint64_t through, bool background) {
  int log = 0, copied = 0;
  const int rc = sqlite3_wal_checkpoint_v2(db, schema, SQLITE_CHECKPOINT_PASSIVE, &log, &copied);
  {
    std::lock_guard lock(mu_);
    // BUSY: the other side was checkpointing at that moment; it did the work.
    if (rc != SQLITE_OK && rc != SQLITE_BUSY) {
      ++stats_.errors;
      stats_.last_error = sqlite3_errstr(rc);
      return;
    }
    if (rc == SQLITE_BUSY || log < 0) return;
    ++(background ? stats_.background : stats_.inline_by_writer);
    stats_.pages_copied += copied;
    stats_.log_pages_last = log;
  }
  if (copied == log) made_durable(through);
}

void BackgroundCheckpoint::loop() {
  std::optional<Db> db;
  for (;;) {
    std::uint64_t through = 0;
    {
      std::unique_lock lock(mu_);
      for (;;) {
        if (stop_) return;
        if (wanted_) break;
        if (!undurable_since_) {
          cv_.wait(lock);
          continue;
        }
        // The time trigger: a slow stream's commits are durable within about
        // durable_within, not only once enough log for the size trigger piled up.
        const auto due = *undurable_since_ + opt_.durable_within;
        if (Clock::now() >= due) {
          ++stats_.time_triggered;
          break;
        }
        cv_.wait_until(lock, due);
      }
      wanted_ = false;
      through = committed_.load();
    }
    try {
      if (!db) {
        db.emplace(Db::open(path_, SQLITE_OPEN_READWRITE));
        db->check(sqlite3_busy_timeout(db->get(), 10000), "busy_timeout");
        // A connection finds the log only when it first reads the file;
        // before that a checkpoint does nothing (and reports -1 pages).
        SqliteStmt mode(*db, "PRAGMA journal_mode");
        if (!mode.step() || mode.col_text(0) != "wal") throw StorageError(path_ + ": not in WAL mode");
      }
      checkpoint(db->get(), "main", through, true);
    } catch (const std::exception& e) {  // could not open: the writer's inline checkpoints keep the log bounded
      std::lock_guard lock(mu_);
      ++stats_.errors;
      stats_.last_error = e.what();
    }
    std::lock_guard lock(mu_);
    // Readers kept the log from being copied whole: try again in a while, not at once.
    if (durable_.load() < through && undurable_since_)
      undurable_since_ = std::max(*undurable_since_, Clock::now() - opt_.durable_within + std::chrono::milliseconds(50));
  }
}

}  // namespace ambdiag::storage::detail
