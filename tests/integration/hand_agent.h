// For tests that play an agent by hand over DDS (an old protocol version,
// a rogue writer): the run header such an agent sends first.
#pragma once

#include <cstdint>
#include <string>

#include "ambdiag/core/run_recording.h"
#include "ambdiag/proto/stream.h"

namespace ambdiag::testing {

// Writes the header of `rec` as run `run_id` with the given protocol
// version and block size (frames).
inline void send_run_header(stream::AgentEndpoints& agent, const RunRecording& rec, const std::string& run_id,
                            uint32_t protocol_version, uint32_t frames_per_block) {
  const std::string header_json = run_to_json(rec).dump();
  ambdiag_stream_RunHeader h{};
  h.protocol_version = protocol_version;
  h.run_id = const_cast<char*>(run_id.c_str());
  h.pump_id = const_cast<char*>(rec.pump_id.c_str());
  h.header_json = const_cast<char*>(header_json.c_str());
  h.n_channels = static_cast<uint32_t>(rec.channels.size());
  h.sample_rate_hz = rec.sample_rate_hz;
  h.frames_per_block = frames_per_block;
  agent.header.write(h);
}

}  // namespace ambdiag::testing
