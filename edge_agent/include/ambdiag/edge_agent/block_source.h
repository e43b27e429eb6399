// Where a run's blocks come from: a recording cut into blocks of
// `frames_per_block` frames (replay, and the simulator's generated runs).
#pragma once

#include <cstdint>
#include <optional>

#include "ambdiag/core/run_recording.h"
#include "ambdiag/edge_agent/block.h"

namespace ambdiag::agent {

class RecordingSource {
 public:
  // `run` must be valid (read_run or validate()).
  RecordingSource(RunRecording run, uint32_t frames_per_block);
  const RunRecording& run() const { return run_; }
  uint32_t frames_per_block() const { return frames_per_block_; }
  int64_t total_frames() const { return run_.frame_count(); }
  int64_t frames_produced() const { return next_frame_; }
  // The next block, or nothing at the end of the run.
  std::optional<Block> next();

 private:
  RunRecording run_;
  uint32_t frames_per_block_;
  int64_t next_frame_ = 0;
  int64_t next_seq_ = 0;
};

}  // namespace ambdiag::agent
