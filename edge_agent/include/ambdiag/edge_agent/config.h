// The agent's configuration file (JSON), e.g.
//   {"pump_id": "P-101", "model": "plant.json", "source": "replay",
//    "schedule": {"identification_interval_s": 3600, "monitoring_interval_s": 60, "runs": 0},
//    "simulation": {"excitation": "multisine", "faults": ["dry_run"], "sample_rate_hz": 2048,
//                   "period_samples": 2048, "f_min_hz": 1, "f_max_hz": 1000, "settle_periods": 2,
//                   "meas_periods": 4, "monitoring_s": 1, "seed": 1, "speed_spread_pct": 2,
//                   "seal_drift_pct": 5, "seal_drift_link_pct": 1},
//    "dds": {"domain": 0, "partition": "site-a", "partition_per_pump": false, "checksum": "xxh64",
//            "protocol": "1.2"},
//    "spool": {"dir": "/var/spool/ambdiag", "limit_bytes": 1073741824, "memory_blocks": 256},
//    "block_frames": 512}
// Every key is optional; unknown keys are refused (a typo must not silently
// fall back to a default). Errors name the file and the key.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace ambdiag::agent {

// The simulated pump (source "simulate"; edge_agent/simulate.h has the
// meaning and defaults of each).
struct SimulationConfig {
  std::string excitation = "multisine";  // multisine | stepsine
  std::vector<std::string> faults;       // NAME[=V|=A..B][@runK[..M]] (simulate.h FaultSchedule)
  double speed_spread_pct = 0.0;         // 0..20; per-run speed, simulate.h
  double seal_drift_pct = 0.0;           // 0..20; per-run seal drift, common
  double seal_drift_link_pct = 0.0;      // 0..20; per-run seal drift, per link
  double sample_rate_hz = 2048.0;
  int64_t period_samples = 2048;
  double f_min_hz = 1.0;
  double f_max_hz = 1000.0;
  int settle_periods = 2;
  int meas_periods = 4;
  double monitoring_s = 1.0;
  uint64_t seed = 1;
};

struct AgentConfig {
  std::string pump_id;                 // empty: taken from the recording
  std::string model;                   // plant model (simulate)
  std::string source = "replay";       // replay | simulate
  // Schedule: an identification run every identification_interval_s
  // (the first at start), a monitoring snapshot every monitoring_interval_s
  // (0: none); the agent stops after `runs` identification runs (0: never).
  double identification_interval_s = 3600.0;
  double monitoring_interval_s = 60.0;
  int64_t runs = 0;
  SimulationConfig simulation;
  int domain = 0;                      // DDS domain id, 0..232
  std::string partition = "site";      // DDS partition: one per site
  // Publish in the pump's own partition "<partition>/<pump_id>" instead of
  // the site's: what DDS Security permissions grant an enrolled agent
  // (deploy/security/ambdiag-pki.sh, docs/streaming.md "Security").
  bool partition_per_pump = false;
  // Checksums of new runs: "xxh64" (protocol 1.1) or "fnv1a64" for a server
  // of protocol 1.0, which knows no other (docs/streaming.md).
  std::string checksum = "xxh64";
  // The protocol minor this agent speaks: "1.2" (durable acks: blocks leave
  // the spool once on the server's disk for good) or "1.1" (as agents before
  // it did; for the version tests). Empty: this build's.
  std::string protocol;
  std::string spool_dir = "ambdiag-spool";
  uint64_t spool_limit_bytes = 1ull << 30;  // segments on disk in the whole spool folder, all runs
  uint32_t memory_blocks = 256;        // unacknowledged blocks kept in memory before the disk
  uint32_t block_frames = 512;         // frames per sample block
};

// Throws InputError naming the file and the key.
AgentConfig load_agent_config(const std::string& path);
// Checks value ranges; throws InputError naming the key and `origin`.
void validate(const AgentConfig& c, const std::string& origin);
// The DDS partition the agent publishes in: the site's, or with
// partition_per_pump its pump's (then pump_id is required and must be a
// plain name). Throws InputError naming `origin`.
std::string dds_partition(const AgentConfig& c, const std::string& origin);

}  // namespace ambdiag::agent
