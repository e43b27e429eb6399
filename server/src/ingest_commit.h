// Private to ambdiag_ingest: the commit thread's side. Stores a batch of
// queued work in one historian transaction, then acknowledges: acks and run
// verdicts leave only after COMMIT returned.
#pragma once

#include <atomic>
#include <string>
#include <utility>
#include <unordered_map>
#include <vector>

#include <nlohmann/json.hpp>

#include "ambdiag/proto/stream.h"
#include "ambdiag/server/ingest.h"
#include "ingest_durable.h"
#include "ingest_work.h"

namespace ambdiag::server::detail {

// One line on stderr when `verbose` (one write, so the two threads' lines
// do not interleave).
void log_line(bool verbose, const std::string& msg);

class Committer {
 public:
  // Registers itself as `historian`'s durability listener (protocol 1.2:
  // the historian must checkpoint in the background) until destroyed.
  Committer(storage::Historian& historian, const IngestOptions& opt, IngestCounters& counters,
            const dds::Writer<ambdiag_stream_Ack>& ack_writer);
  ~Committer();
  Committer(const Committer&) = delete;
  Committer& operator=(const Committer&) = delete;

  // All of `batch` in one transaction. A refused item (conflicting chunk,
  // bad header, ...) is rejected and counted and the rest goes on; a
  // StorageError rolls everything back: counted, logged, nothing
  // acknowledged, but for a TransientError (PostgreSQL broke a deadlock),
  // after which the batch is run again from the start (at most 5 times). After the commit: acks of what is committed to 1.2
  // agents at once (flow control); acks that say durable, and every
  // verdict, once the commit is durable.
  void commit(std::vector<Work>& batch);
  // A clean stop: waits (at most `timeout`) for the held acks to go out.
  void drain(std::chrono::milliseconds timeout) { durable_acks_.drain(timeout); }
  // A commit found the ingest group's lease lost (IngestOptions::fence):
  // nothing more is committed (commit() returns at once) or acknowledged.
  bool fenced() const { return fenced_.load(); }

 private:
  // The run's checksum (of `kind`) over chunks 0..next_seq-1 as this server
  // stored them; lets end_run skip reading the run back (storage::HeldDigest).
  struct Chain {
    int64_t next_seq = 0;
    uint64_t hash = kFnv1a64Init;
    ChecksumKind kind = ChecksumKind::fnv1a64;
  };
  using Ack = AckMsg;
  // What a batch did, applied after its commit.
  struct Staged {
    std::unordered_map<std::string, Chain> chains;  // runs touched: their chains after the batch
    std::unordered_map<std::string, bool> ended;    // runs with a verdict in this batch
    std::unordered_map<std::string, std::vector<int64_t>> stored_seqs;
    std::unordered_map<std::string, uint32_t> agent_minor;  // the oldest sender of each run's blocks
    std::vector<Ack> verdicts;
    std::vector<std::string> log;
    std::vector<std::string> completed;  // runs that became complete in this batch
    std::vector<std::string> rejected;   // the reasons of the items refused (counted at the commit)
    int64_t blocks_stored = 0, blocks_duplicate = 0, bytes_stored = 0, headers = 0, complete = 0, incomplete = 0,
            monitoring_stored = 0, monitoring_duplicate = 0, from_digest = 0;
    bool stream_progress = false;  // blocks stored or a run ended
  };

  void apply(BeginRun& w, Staged& st);
  void apply(Blocks& w, Staged& st);
  void apply(EndRun& w, Staged& st);
  void apply(MarkIncomplete& w, Staged& st);
  void apply(Monitoring& w, Staged& st);
  Chain& chain(Staged& st, const std::string& run_id);
  void verdict(Staged& st, const std::string& run_id, const std::string& pump_id, std::optional<storage::RunStatus> before,
               storage::RunStatus after, const std::string& reason);
  void reject(Staged& st, const std::string& reason, const std::string& run_id, const std::string& what);
  void send(const Ack& a);
  // The stored blocks as acks of seq ranges.
  static std::vector<Ack> ack_ranges(const std::string& run_id, std::vector<int64_t> seqs);
  bool durable_acks() const;  // this server speaks 1.2 or later

  storage::Historian& h_;
  const IngestOptions& opt_;
  IngestCounters& counters_;
  const dds::Writer<ambdiag_stream_Ack>& ack_writer_;
  std::unordered_map<std::string, Chain> chains_;
  std::atomic<bool> fenced_{false};
  DurableAcks durable_acks_;  // last: its thread stops before the rest goes
};

}  // namespace ambdiag::server::detail
