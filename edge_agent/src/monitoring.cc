#include "ambdiag/edge_agent/monitoring.h"

#include <chrono>
#include <cstdio>
#include <exception>

#include "ambdiag/edge_agent/schedule.h"

namespace ambdiag::agent {

ambdiag_stream_MonitoringSnapshot to_message(const std::string& pump_id, const Snapshot& s, int64_t time_ns) {
  ambdiag_stream_MonitoringSnapshot m{};
  m.protocol_version = stream::kProtocolVersion;
  m.pump_id = const_cast<char*>(pump_id.c_str());  // the C type is not const; DDS only reads it
  m.time_ns = time_ns;
  m.speed_rpm = s.speed_rpm;
  for (size_t k = 0; k < 4; ++k) {
    m.force_1x_amp_n[k] = s.force_1x_amp_n[k];
    m.force_1x_phase_rad[k] = s.force_1x_phase_rad[k];
    m.force_2x_amp_n[k] = s.force_2x_amp_n[k];
    m.force_2x_phase_rad[k] = s.force_2x_phase_rad[k];
  }
  for (size_t b = 0; b < 2; ++b) {
    m.orbit_major_m[b] = s.orbit_major_m[b];
    m.orbit_minor_m[b] = s.orbit_minor_m[b];
    m.orbit_center_x_m[b] = s.orbit_center_x_m[b];
    m.orbit_center_y_m[b] = s.orbit_center_y_m[b];
  }
  return m;
}

SnapshotPublisher::SnapshotPublisher(stream::AgentEndpoints& ep, std::string pump_id,
                                     std::unique_ptr<PumpSimulator> sim, double interval_s)
    : ep_(ep), pump_id_(std::move(pump_id)), sim_(std::move(sim)), interval_s_(interval_s) {
  thread_ = std::thread([this] { run(); });
}

SnapshotPublisher::~SnapshotPublisher() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

void SnapshotPublisher::run() {
  using clock = std::chrono::steady_clock;
  const auto t0 = clock::now();
  auto seconds = [&] { return std::chrono::duration<double>(clock::now() - t0).count(); };
  Ticker ticker(interval_s_, 0.0);
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stop_) {
    if (ticker.due(seconds())) {
      lock.unlock();
      try {
        sim_->set_operating_state(run_);
        const Snapshot s = sim_->monitoring_snapshot();
        const auto now_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                                std::chrono::system_clock::now().time_since_epoch()).count();
        ep_.monitoring.write(to_message(pump_id_, s, now_ns));
        ++published_;
      } catch (const std::exception& e) {
        std::fprintf(stderr, "ambdiag-agent: monitoring snapshot failed: %s\n", e.what());
      }
      ticker.done(seconds());
      lock.lock();
      continue;
    }
    wake_.wait_for(lock, std::chrono::duration<double>(ticker.next_s() - seconds()));
  }
}

}  // namespace ambdiag::agent
