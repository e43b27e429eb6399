// Private to ambdiag_ingest: acknowledgements that may leave only once the
// commit that stored what they acknowledge is durable (protocol 1.2,
// docs/streaming.md "Durable acknowledgement"). The commit thread holds them
// under its commit's number (Historian::commit_generation); the historian's
// durability listener releases them, and a thread of this class sends them,
// so neither the checkpoint thread nor the commit thread waits for DDS.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "ambdiag_stream.h"

namespace ambdiag::server::detail {

struct AckMsg {
  std::string run_id;
  int64_t first = -1, last = -1;  // a block range, or -1 for a verdict
  ambdiag_stream_AckState state = ambdiag_stream_ACK_STORED;
  std::string message;
  bool durable = false;
};

class DurableAcks {
 public:
  explicit DurableAcks(std::function<void(const AckMsg&)> send);
  ~DurableAcks();  // what is still held is not sent: the agents re-send those blocks and ends
  DurableAcks(const DurableAcks&) = delete;
  DurableAcks& operator=(const DurableAcks&) = delete;

  // Sends `acks` once commit `generation` is durable (at once if it is).
  void hold(uint64_t generation, std::vector<AckMsg> acks);
  // Commits up to `generation` are durable (the historian's listener).
  void durable(uint64_t generation);
  // Waits until nothing is held or `timeout` passes (a clean stop).
  void drain(std::chrono::milliseconds timeout);

 private:
  void loop();

  std::function<void(const AckMsg&)> send_;
  std::mutex mu_;
  std::condition_variable cv_, drained_cv_;
  uint64_t durable_ = 0;
  std::deque<std::pair<uint64_t, std::vector<AckMsg>>> held_;  // in commit order
  bool sending_ = false, stop_ = false;
  std::thread thread_;
};

}  // namespace ambdiag::server::detail
