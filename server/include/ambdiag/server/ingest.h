// The server's DDS side: receives runs and monitoring snapshots from every
// agent, validates each message, stores them in the historian and
// acknowledges blocks after commit (docs/streaming.md).
//
// Two threads, so that receiving and committing overlap: the receive thread
// takes DDS samples, validates them (sizes, block checksum, finite samples,
// run header) and queues the work; the commit thread stores everything
// queued in one historian transaction (WriteBatch) and then sends the acks.
// The queue is bounded in bytes: when it is full the receive thread stops
// taking blocks, the DDS reader (max 256 samples) fills and pushes back on
// the agents' writers, and the agents keep the backlog in their spools.
//
// A bad message (incompatible version, wrong sizes, oversized payload,
// checksum mismatch, non-finite samples, a header that is not a valid
// run.json, a block conflicting with one already stored, an invalid
// monitoring snapshot) is rejected, logged and counted by reason; ingest
// keeps running. A run whose agent stops sending heartbeats and data for
// `agent_timeout` before its run end is marked incomplete, as is a run that
// ends aborted or fails the historian's count/checksum check.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace ambdiag::storage {
class Historian;
}

namespace ambdiag::server {

class MetricsRegistry;

struct IngestOptions {
  int domain = 0;
  std::vector<std::string> partitions{"*"};  // every site
  std::chrono::milliseconds agent_timeout{10000};
  // A transaction takes what is queued, up to these. Smaller than what the
  // agents have in flight (4 x 128 blocks of 30 KiB = 15 MiB), so that while
  // one batch commits the next arrives: a batch as large as everything in
  // flight would leave the agents waiting for acks during every commit.
  size_t max_batch_blocks = 256;        // blocks per historian transaction, at most
  size_t max_batch_bytes = 4u << 20;    // payload bytes per transaction, at most
  size_t max_queue_bytes = 16u << 20;   // received, validated, not yet committed
  // Commits start at most this often unless half a batch is waiting: paced
  // pumps send 16 blocks/s each, and a transaction per block costs the
  // server more CPU than the block; acks come at most this much later.
  std::chrono::milliseconds min_commit_interval{20};
  bool verbose = true;                  // log runs and rejections on stderr
  // Added to every commit: emulates a slow disk (bench_stream's memory check).
  std::chrono::milliseconds commit_delay{0};
  // Called from the commit thread after the commit that made a run
  // complete (wakes the analysis workers of this process); must be quick
  // and must not throw.
  std::function<void(const std::string& run_id)> on_run_complete;
  // Called inside the commit's transaction, on the ingest's connection, for
  // each run the transaction makes complete: what it writes (the run's
  // analysis job) commits with the run or not at all, so the analysis need
  // not run in this process, nor be told. An InputError is logged and the
  // run stored all the same; a StorageError fails the commit (the agents
  // re-send). May be empty.
  std::function<void(storage::Historian&, const std::string& run_id)> in_commit_run_complete;
  // Speak an older minor of the protocol (the version tests: a 1.1 server
  // acknowledges blocks and verdicts once committed, never as durable).
  // Unset: this build's (1.2, durable acknowledgements).
  std::optional<uint32_t> speak_protocol_minor;
  // The ingest group's lease (ingest_group.h): called from the commit
  // thread inside each commit's transaction, before anything is written,
  // with the ingest's historian. False means this process no longer holds
  // its group: the batch rolls back, nothing of it is acknowledged, the
  // acknowledgements still held for durability are dropped and run()
  // returns at once. Unset: always holding (a server alone).
  std::function<bool(storage::Historian&)> fence;
};

// Counters, readable from any thread (REST health).
struct IngestCounters {
  std::atomic<int64_t> headers{0}, blocks_received{0}, blocks_stored{0}, blocks_duplicate{0}, bytes_stored{0},
      commits{0}, runs_complete{0}, runs_incomplete{0}, blocks_orphan{0}, acks_sent{0}, heartbeats{0},
      monitoring_stored{0}, monitoring_duplicate{0}, storage_errors{0}, queue_bytes{0}, queue_peak_bytes{0},
      runs_verified_from_digest{0},
      blocks_acked_durable{0},  // block acknowledgements sent as durable (protocol 1.2), counted per block
      blocks_rejected_by_dds{0},  // refused by the block reader's resource limits (re-sent by DDS)
      commits_fenced{0};  // batches rolled back because the ingest group's lease was lost (IngestOptions::fence)
  // Steady-clock ns of the first block received and of the last commit that
  // stored blocks or ended a run: their difference is the streaming span.
  std::atomic<int64_t> first_block_ns{0}, last_commit_ns{0};
  // Rejections by reason: version, oversized, size, checksum, non_finite,
  // header, conflict, run_end, monitoring, pump_partition (a writer bound to
  // another pump), dds_security (Cyclone's security plugins refused a
  // remote participant or endpoint: docs/streaming.md, "Security").
  void reject(const std::string& reason);
  int64_t rejected_total() const;
  std::map<std::string, int64_t> rejected_by_reason() const;
  nlohmann::json to_json() const;

 private:
  mutable std::mutex mu_;
  std::map<std::string, int64_t> rejected_;
};

class Ingest {
 public:
  // `historian` must be open for writing and is used from run()'s threads only.
  Ingest(storage::Historian& historian, IngestOptions opt);
  ~Ingest();
  Ingest(const Ingest&) = delete;
  Ingest& operator=(const Ingest&) = delete;

  enum class End {
    stopped,  // stop_flag: what was queued is committed, the held acks sent (at most 3 s)
    fenced    // the group is lost (fence, lost_flag): nothing more committed or acknowledged
  };
  // Joins DDS (the readers and the ack writer exist only while it runs: a
  // standby has none, and agents see a server appear when it starts) and
  // receives until `stop_flag` is set (checked every 100 ms, so a signal
  // handler may set it) or the group is lost (the fence fails, or
  // `lost_flag` is set by whoever found another holder), then leaves DDS
  // and returns. Runs the commit thread itself; a StorageError of a commit
  // is logged and counted, nothing of that batch is acknowledged (the
  // agents re-send it). May be called again after it returned (a standby
  // that took over again).
  End run(const std::atomic<bool>& stop_flag, const std::atomic<bool>& lost_flag);
  End run(const std::atomic<bool>& stop_flag);  // a server alone: never lost
  const IngestCounters& counters() const { return counters_; }
  nlohmann::json health() const { return counters_.to_json(); }

  struct Impl;

 private:
  storage::Historian& historian_;
  IngestOptions opt_;
  IngestCounters counters_;
};

// Ingest's counters as metrics (GET /metrics): runs received by outcome,
// blocks, bytes, rejected samples by reason, the queue. They count from
// this process' start. `ingest` must outlive the registry's scrapes.
void register_ingest_metrics(MetricsRegistry& registry, const Ingest& ingest);

}  // namespace ambdiag::server
