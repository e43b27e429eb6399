// The checksum that ties a streamed run to what was recorded: FNV-1a 64 over
// the run's samples.f32 bytes in sample order. The agent sends it in the run
// end message; the server recomputes it from the chunks in its historian.
// Not cryptographic: it catches loss, duplication, reordering and bit errors.
#pragma once

#include <cstddef>
#include <cstdint>

namespace ambdiag {

inline constexpr std::uint64_t kFnv1a64Init = 14695981039346656037ull;

// Continues a running checksum over more bytes: feeding a run chunk by chunk
// gives the same value as feeding it in one call.
std::uint64_t fnv1a64(const void* data, std::size_t n_bytes, std::uint64_t state = kFnv1a64Init);

// Continues two running checksums over the same bytes in one pass, e.g. a
// block's own (from kFnv1a64Init) and its run's. Same values as two fnv1a64
// calls at about the cost of one: FNV is a chain of dependent multiplies, and
// two independent chains run side by side in the CPU.
void fnv1a64_pair(const void* data, std::size_t n_bytes, std::uint64_t& state_a, std::uint64_t& state_b);

}  // namespace ambdiag
