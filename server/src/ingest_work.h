// Private to ambdiag_ingest: the work the receive thread hands to the commit
// thread, in arrival order, through a queue bounded in bytes.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <variant>
#include <vector>

#include "ambdiag/storage/historian.h"

namespace ambdiag::server::detail {

struct ValidBlock {
  int64_t seq = 0, first_frame = 0, n_frames = 0;
  std::vector<uint8_t> bytes;
  // Set when the receive thread hashed this block right after seq - 1 of the
  // same run: the run's checksum (of `kind`) before and after it (see Chain).
  bool chained = false;
  uint64_t run_hash_before = 0, run_hash_after = 0;
  ChecksumKind kind = ChecksumKind::fnv1a64;
  uint32_t protocol_minor = 0;  // the sender's: 1.2 agents get committed and durable acks
};

struct BeginRun {
  storage::RunHeader header;
};
struct Blocks {
  std::string run_id;
  std::vector<ValidBlock> blocks;
};
struct EndRun {
  std::string run_id;
  int64_t total_frames = 0;
  uint64_t checksum = 0;
  ChecksumKind kind = ChecksumKind::fnv1a64;
  bool aborted = false;
  std::string reason;
};
struct MarkIncomplete {  // the agent fell silent
  std::string run_id, reason;
};
struct Monitoring {
  std::vector<storage::MonitoringSnapshot> snapshots;
};
using Work = std::variant<BeginRun, Blocks, EndRun, MarkIncomplete, Monitoring>;

inline size_t payload_bytes(const Work& w) {
  size_t n = 0;
  if (const auto* b = std::get_if<Blocks>(&w))
    for (const auto& x : b->blocks) n += x.bytes.size();
  return n;
}

// FIFO of work, bounded by the sample bytes it holds. push() never blocks
// (the producer asks has_room() before taking more blocks off DDS; control
// messages are small and always fit); pop_batch() waits for work.
class WorkQueue {
 public:
  explicit WorkQueue(size_t max_bytes) : max_bytes_(max_bytes) {}

  bool has_room() const {
    std::lock_guard lock(mu_);
    return bytes_ < max_bytes_;
  }
  // Waits until there is room (or the timeout passes); true if there is.
  bool wait_for_room(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mu_);
    return room_cv_.wait_for(lock, timeout, [&] { return bytes_ < max_bytes_; });
  }
  size_t bytes() const {
    std::lock_guard lock(mu_);
    return bytes_;
  }
  // Returns the bytes queued after the push.
  size_t push(Work w) {
    std::lock_guard lock(mu_);
    bytes_ += payload_bytes(w);
    items_.push_back(std::move(w));
    cv_.notify_one();
    return bytes_;
  }
  // Waits up to `timeout` for work, then takes items in order while they fit
  // in max_blocks / max_bytes (always at least one).
  std::vector<Work> pop_batch(size_t max_blocks, size_t max_bytes, std::chrono::milliseconds timeout) {
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, timeout, [&] { return !items_.empty(); });
    std::vector<Work> out;
    size_t blocks = 0, bytes = 0;
    while (!items_.empty()) {
      const auto* b = std::get_if<Blocks>(&items_.front());
      const size_t nb = b ? b->blocks.size() : 0, nbytes = payload_bytes(items_.front());
      if (!out.empty() && (blocks + nb > max_blocks || bytes + nbytes > max_bytes)) break;
      blocks += nb;
      bytes += nbytes;
      bytes_ -= nbytes;
      out.push_back(std::move(items_.front()));
      items_.pop_front();
    }
    if (!out.empty()) room_cv_.notify_all();
    return out;
  }

 private:
  const size_t max_bytes_;
  mutable std::mutex mu_;
  std::condition_variable cv_, room_cv_;
  std::deque<Work> items_;
  size_t bytes_ = 0;
};

}  // namespace ambdiag::server::detail
