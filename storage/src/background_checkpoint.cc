#include "background_checkpoint.h"

#include <pthread.h>

#include <optional>

#include "sqlite_db.h"

namespace ambdiag::storage::detail {

BackgroundCheckpoint::BackgroundCheckpoint(sqlite3* writer, std::string path, int trigger_pages, int inline_pages)
    : writer_(writer), path_(std::move(path)), trigger_pages_(trigger_pages), inline_pages_(inline_pages) {
  thread_ = std::thread([this] {
    pthread_setname_np(pthread_self(), "ambdiag-ckpt");
    loop();
  });
  sqlite3_wal_hook(writer_, &BackgroundCheckpoint::on_commit, this);
}

BackgroundCheckpoint::~BackgroundCheckpoint() {
  sqlite3_wal_autocheckpoint(writer_, 1000);  // SQLite's default hook again
  {
    std::lock_guard lock(mu_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

CheckpointStats BackgroundCheckpoint::stats() const {
  std::lock_guard lock(mu_);
  return stats_;
}

// Runs in the writer's thread, right after its commit.
int BackgroundCheckpoint::on_commit(void* self_ptr, sqlite3* db, const char* schema, int pages) {
  auto& self = *static_cast<BackgroundCheckpoint*>(self_ptr);
  if (pages >= self.inline_pages_) {
    int log = 0, copied = 0;
    const int rc = sqlite3_wal_checkpoint_v2(db, schema, SQLITE_CHECKPOINT_PASSIVE, &log, &copied);
    self.record(rc, log, copied, false);
  } else if (pages >= self.trigger_pages_) {
    {
      std::lock_guard lock(self.mu_);
      self.wanted_ = true;
    }
    self.cv_.notify_one();
  }
  return SQLITE_OK;  // a failed checkpoint is counted, never the commit's failure
}

void BackgroundCheckpoint::record(int rc, int log_pages, int copied_pages, bool background) {
  std::lock_guard lock(mu_);
  // BUSY: the other side was checkpointing at that moment; it did the work.
  if (rc != SQLITE_OK && rc != SQLITE_BUSY) {
    ++stats_.errors;
    stats_.last_error = sqlite3_errstr(rc);
    return;
  }
  if (rc == SQLITE_BUSY || log_pages < 0) return;
  ++(background ? stats_.background : stats_.inline_by_writer);
  stats_.pages_copied += copied_pages;
  stats_.log_pages_last = log_pages;
}

void BackgroundCheckpoint::loop() {
  std::optional<Db> db;
  for (;;) {
    {
      std::unique_lock lock(mu_);
      cv_.wait(lock, [&] { return wanted_ || stop_; });
      if (stop_) return;
      wanted_ = false;
    }
    try {
      if (!db) {
        db.emplace(Db::open(path_, SQLITE_OPEN_READWRITE));
        db->check(sqlite3_busy_timeout(db->get(), 10000), "busy_timeout");
        // A connection finds the log only when it first reads the file;
        // before that a checkpoint does nothing (and reports -1 pages).
        Stmt mode(*db, "PRAGMA journal_mode");
        if (!mode.step() || mode.col_text(0) != "wal") throw StorageError(path_ + ": not in WAL mode");
      }
      int log = 0, copied = 0;
      const int rc = sqlite3_wal_checkpoint_v2(db->get(), "main", SQLITE_CHECKPOINT_PASSIVE, &log, &copied);
      record(rc, log, copied, true);
    } catch (const std::exception& e) {  // could not open: the writer's inline checkpoints keep the log bounded
      std::lock_guard lock(mu_);
      ++stats_.errors;
      stats_.last_error = e.what();
    }
  }
}

}  // namespace ambdiag::storage::detail
