// The agent's configuration file (JSON), e.g.
//   {"pump_id": "P-101", "model": "plant.json", "source": "replay",
//    "schedule": {"identification_interval_s": 3600, "monitoring_interval_s": 60},
//    "dds": {"domain": 0, "partition": "site-a"},
//    "spool": {"dir": "/var/spool/ambdiag", "limit_bytes": 1073741824, "memory_blocks": 256},
//    "block_frames": 512}
// Every key is optional; unknown keys are refused (a typo must not silently
// fall back to a default). Errors name the file and the key.
#pragma once

#include <cstdint>
#include <string>

namespace ambdiag::agent {

struct AgentConfig {
  std::string pump_id;                 // empty: taken from the recording
  std::string model;                   // plant model (simulate)
  std::string source = "replay";       // replay | simulate
  double identification_interval_s = 3600.0;
  double monitoring_interval_s = 60.0;
  int domain = 0;                      // DDS domain id, 0..232
  std::string partition = "site";      // DDS partition: one per site
  std::string spool_dir = "ambdiag-spool";
  uint64_t spool_limit_bytes = 1ull << 30;
  uint32_t memory_blocks = 256;        // unacknowledged blocks kept in memory before the disk
  uint32_t block_frames = 512;         // frames per sample block
};

// Throws InputError naming the file and the key.
AgentConfig load_agent_config(const std::string& path);
// Checks value ranges; throws InputError naming the key and `origin`.
void validate(const AgentConfig& c, const std::string& origin);

}  // namespace ambdiag::agent
