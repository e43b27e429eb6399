// Private to ambdiag_storage: copies the writer's write-ahead log into the
// database file from a thread and connection of its own (docs/storage.md,
// "Checkpoints"), so a commit never waits for a checkpoint's fsyncs.
#pragma once

#include <sqlite3.h>

#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

#include "ambdiag/storage/historian.h"

namespace ambdiag::storage::detail {

class BackgroundCheckpoint {
 public:
  // Installs itself as `writer`'s WAL hook (which replaces SQLite's
  // automatic checkpoint): after a commit that leaves `trigger_pages` or
  // more in the log the thread checkpoints; should it fall behind until
  // `inline_pages` are in the log, the committing writer checkpoints itself,
  // so the log stays bounded either way.
  BackgroundCheckpoint(sqlite3* writer, std::string path, int trigger_pages, int inline_pages);
  ~BackgroundCheckpoint();  // finishes a running checkpoint, restores SQLite's automatic one
  BackgroundCheckpoint(const BackgroundCheckpoint&) = delete;
  BackgroundCheckpoint& operator=(const BackgroundCheckpoint&) = delete;

  CheckpointStats stats() const;

 private:
  static int on_commit(void* self, sqlite3* db, const char* schema, int pages);
  void loop();
  void record(int rc, int log_pages, int copied_pages, bool background);

  sqlite3* writer_;
  const std::string path_;
  const int trigger_pages_, inline_pages_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  bool wanted_ = false, stop_ = false;
  CheckpointStats stats_;
  std::thread thread_;
};

}  // namespace ambdiag::storage::detail
