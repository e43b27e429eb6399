// A block of consecutive frames of a run, as the agent stores and sends it.
#pragma once

#include <cstdint>
#include <string>

namespace ambdiag::agent {

struct Block {
  int64_t seq = 0;          // 0, 1, 2, ... within the run
  int64_t first_frame = 0;  // index of the block's first frame in the run
  uint32_t n_frames = 0;
  uint64_t checksum = 0;    // of payload, of the run's checksum kind (SpooledHeader)
  std::string payload;      // float32 LE, frame-major, channel-minor
};

}  // namespace ambdiag::agent
