// The chunks bench_storage and bench_pg_ingest store: 32 KiB of seeded
// float32 samples each (512 frames x 16 channels), as the agents send them,
// and the run.json of their run.
#pragma once

#include <cstdint>
#include <cstring>
#include <random>
#include <span>
#include <string>
#include <vector>

#include "ambdiag/storage/historian.h"

namespace ambdiag::bench {

constexpr int kChannels = 16;
constexpr std::int64_t kFramesPerChunk = 512;
constexpr std::size_t kChunkBytes = kChannels * 4 * kFramesPerChunk;

// n_chunks chunks' worth of normal float32 samples (seed 1).
inline std::vector<std::uint8_t> seeded_samples(std::size_t n_chunks) {
  std::vector<std::uint8_t> data(n_chunks * kChunkBytes);
  std::mt19937 rng(1);
  std::normal_distribution<float> d;
  for (std::size_t i = 0; i < data.size(); i += 4) {
    const float x = d(rng);
    std::memcpy(&data[i], &x, 4);
  }
  return data;
}

// The samples as chunks seq 0, 1, ... (views into `data`).
inline std::vector<storage::Chunk> chunks_of(const std::vector<std::uint8_t>& data) {
  std::vector<storage::Chunk> chunks;
  for (std::size_t i = 0; i < data.size() / kChunkBytes; ++i)
    chunks.push_back({static_cast<std::int64_t>(i), static_cast<std::int64_t>(i) * kFramesPerChunk, kFramesPerChunk,
                      std::span(data).subspan(i * kChunkBytes, kChunkBytes)});
  return chunks;
}

// A monitoring run of pump P-1 with kChannels displacement channels.
inline std::string run_json(const std::string& run_id) {
  std::string j = R"({"format": "ambdiag.run/1", "pump_id": "P-1", "run_id": ")" + run_id +
                  R"(", "kind": "monitoring", "started_at": "2026-11-22T00:00:00Z", "speed_rpm": 3000,)"
                  R"( "sample_rate_hz": 8000, "channels": [)";
  for (int c = 0; c < kChannels; ++c)
    j += std::string(c ? ", " : "") + R"({"name": "x)" + std::to_string(c) + R"(", "role": "displacement", "unit": "m"})";
  return j + "]}";
}

}  // namespace ambdiag::bench
