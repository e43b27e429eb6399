// The server's DDS side: receives runs from every agent, validates each
// message, stores blocks in the historian in batched transactions and
// acknowledges them after commit (docs/streaming.md).
//
// A bad message (incompatible version, wrong sizes, oversized payload,
// checksum mismatch, non-finite samples, a header that is not a valid
// run.json, a block conflicting with one already stored) is rejected,
// logged and counted by reason; ingest keeps running. A run whose agent
// stops sending heartbeats and data for `agent_timeout` before its run end
// is marked incomplete, as is a run that ends aborted or fails the
// historian's count/checksum check.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::storage {
class Historian;
}

namespace ambdiag::server {

struct IngestOptions {
  int domain = 0;
  std::vector<std::string> partitions{"*"};  // every site
  std::chrono::milliseconds agent_timeout{10000};
  size_t max_batch_blocks = 256;  // blocks per historian transaction
  bool verbose = true;            // log runs and rejections on stderr
  // Added to every commit: emulates a slow disk (bench_stream's memory check).
  std::chrono::milliseconds commit_delay{0};
};

// Counters, readable from any thread (REST health).
struct IngestCounters {
  std::atomic<int64_t> headers{0}, blocks_received{0}, blocks_stored{0}, blocks_duplicate{0}, bytes_stored{0},
      commits{0}, runs_complete{0}, runs_incomplete{0}, blocks_orphan{0}, acks_sent{0}, heartbeats{0};
  // Rejections by reason: version, oversized, size, checksum, non_finite,
  // header, conflict, run_end.
  void reject(const std::string& reason);
  int64_t rejected_total() const;
  nlohmann::json to_json() const;

 private:
  mutable std::mutex mu_;
  std::map<std::string, int64_t> rejected_;
};

class Ingest {
 public:
  // `historian` must be open for writing and is used from run()'s thread only.
  Ingest(storage::Historian& historian, IngestOptions opt);
  ~Ingest();
  Ingest(const Ingest&) = delete;
  Ingest& operator=(const Ingest&) = delete;

  // Receives until stop() is called (from any thread or a signal handler
  // via a flag checked every 100 ms).
  void run(const std::atomic<bool>& stop_flag);
  const IngestCounters& counters() const { return counters_; }
  nlohmann::json health() const { return counters_.to_json(); }

  struct Impl;

 private:
  IngestCounters counters_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace ambdiag::server
