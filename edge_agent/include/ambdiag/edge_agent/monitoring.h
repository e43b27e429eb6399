// Monitoring snapshots of a simulated pump, published on the
// MonitoringSnapshot topic (docs/streaming.md) every `interval_s` from a
// thread of its own, so that a long identification run being streamed
// does not hold them up. Each snapshot simulates `monitoring_s` of the pump
// without excitation (simulate.h) and reports its 1x/2x bearing forces and
// orbits.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "ambdiag/edge_agent/simulate.h"
#include "ambdiag/proto/stream.h"

namespace ambdiag::agent {

// The DDS message of a snapshot; its pump_id points into `pump_id`.
ambdiag_stream_MonitoringSnapshot to_message(const std::string& pump_id, const Snapshot& s, int64_t time_ns);

class SnapshotPublisher {
 public:
  // Starts publishing at once, then every interval_s.
  SnapshotPublisher(stream::AgentEndpoints& ep, std::string pump_id, std::unique_ptr<PumpSimulator> sim,
                    double interval_s);
  ~SnapshotPublisher();  // stops and joins the thread
  SnapshotPublisher(const SnapshotPublisher&) = delete;
  SnapshotPublisher& operator=(const SnapshotPublisher&) = delete;
  long published() const { return published_; }
  // Snapshots from now on show the pump of identification run n (its
  // speed, seal drift and faults: PumpSimulator::set_operating_state).
  void follow_run(int64_t n) { run_ = n; }

 private:
  void run();

  stream::AgentEndpoints& ep_;
  std::string pump_id_;
  std::unique_ptr<PumpSimulator> sim_;
  double interval_s_;
  std::atomic<long> published_{0};
  std::atomic<int64_t> run_{1};
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace ambdiag::agent
