#include "ambdiag/edge_agent/block_source.h"

#include <algorithm>
#include <bit>
#include <stdexcept>


namespace ambdiag::agent {

static_assert(std::endian::native == std::endian::little, "payloads are float32 little-endian");

RecordingSource::RecordingSource(RunRecording run, uint32_t frames_per_block)
    : run_(std::move(run)), frames_per_block_(frames_per_block) {
  if (frames_per_block_ == 0) throw std::invalid_argument("frames_per_block must be > 0");
}

std::optional<Block> RecordingSource::next() {
  const int64_t total = run_.frame_count();
  if (next_frame_ >= total) return std::nullopt;
  const int64_t n = std::min<int64_t>(frames_per_block_, total - next_frame_);
  const size_t n_ch = run_.channels.size();
  Block b;
  b.seq = next_seq_++;
  b.first_frame = next_frame_;
  b.n_frames = static_cast<uint32_t>(n);
  const auto* first = reinterpret_cast<const char*>(run_.samples.data() + static_cast<size_t>(next_frame_) * n_ch);
  b.payload.assign(first, static_cast<size_t>(n) * n_ch * sizeof(float));
  // b.checksum: set by the streamer, in the same pass as the run's checksum.
  next_frame_ += n;
  return b;
}

}  // namespace ambdiag::agent
